//! Hints that start a cache line's load without waiting for it.
//!
//! A plain load that misses holds the head of the core's reorder buffer until its line
//! arrives: issued early, it overlaps only the few hundred instructions behind it. A prefetch
//! retires at once, so a chain of dependent misses (a merge's table slot, then its ranges'
//! points and records) can be started well before the work that reads them, and overlap the
//! shadow rays traced in between. On x86 it is SSE's `prefetcht0`, through `safe_arch`'s safe
//! wrapper; elsewhere a prefetch does nothing.

/// Starts loading the cache line that holds the start of `value` into every cache level.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse"
    ))]
    safe_arch::prefetch_t0(value);
    #[cfg(not(all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse"
    )))]
    let _ = value;
}

/// Bytes of a cache line on the CPUs a prefetch serves.
const LINE: usize = 64;

/// Prefetches every cache line the items `range` of `items` occupy, once each, for items of at
/// most a cache line (of larger ones, `line_openers` names only some lines).
#[inline]
pub fn prefetch_lines<T>(items: &[T], range: std::ops::Range<usize>) {
    let base = items.as_ptr() as usize;
    for i in line_openers(base, std::mem::size_of::<T>(), range) {
        if let Some(item) = items.get(i) {
            prefetch(item);
        }
    }
}

/// The items, of `size` bytes from address `base` on, whose starts name each cache line of the
/// items `range` once. For items of at most a cache line every such line holds the start of
/// one of them, but for the line where the last one ends, which holds the start of the item
/// after it (`range.end`; the caller skips it where there is none). Larger items leave lines
/// between their starts out.
fn line_openers(
    base: usize,
    size: usize,
    range: std::ops::Range<usize>,
) -> impl Iterator<Item = usize> {
    let line = move |i: usize| (base + i * size) / LINE;
    let last = (!range.is_empty() && size > 0).then(|| (base + range.end * size - 1) / LINE);
    let mut previous = None;
    (range.start..=range.end)
        .take_while(move |&i| last.is_some_and(|last| line(i) <= last))
        .filter(move |&i| {
            let fresh = previous != Some(line(i));
            previous = Some(line(i));
            fresh
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each line from the first item's start to the last one's end, once, for records of the
    /// sizes the merges read at any alignment.
    #[test]
    fn every_line_of_a_range_once() {
        for size in [4, 16, 20, 36, 52, 64] {
            for base in (0..128).map(|b| 4096 + b * 4) {
                for range in [0..0, 0..1, 2..3, 3..40, 7..8, 5..105] {
                    let lines: Vec<usize> = line_openers(base, size, range.clone())
                        .map(|i| (base + i * size) / LINE)
                        .collect();
                    let expected: Vec<usize> = if range.is_empty() {
                        Vec::new()
                    } else {
                        let first = (base + range.start * size) / LINE;
                        (first..=(base + range.end * size - 1) / LINE).collect()
                    };
                    assert_eq!(lines, expected, "size {size}, base {base}, {range:?}");
                }
            }
        }
    }

    /// The line after the last item is named by an item that does not exist: skipped.
    #[test]
    fn ranges_to_the_slice_end_stay_in_it() {
        let items: Vec<[u8; 36]> = (0..100u8).map(|i| [i; 36]).collect();
        for range in [0..100, 99..100, 64..100] {
            prefetch_lines(&items, range);
        }
    }
}
