//! What vmerge reads and where it writes, checked before any work: inputs are regular files
//! (never a FIFO, which would block, nor a device or a directory) within a size limit per
//! kind, and an output lies in an existing, writable directory, is not a directory and is not
//! one of the render's inputs. An output being written is locked against other processes
//! ([`lock_output`]).

use std::borrow::Cow;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};
use thiserror::Error;

/// A file that cannot be used, and why.
#[derive(Debug, Error, PartialEq)]
#[error("{}: {message}", show(file))]
pub struct FileError {
    pub file: PathBuf,
    pub message: String,
}

/// The kinds of input, each with its size limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Scene,
    Obj,
    Mtl,
    Exr,
    /// A pbrt-v4 scene file (inline meshes can make it large).
    Pbrt,
    Ply,
}

impl Kind {
    /// The largest file of the kind that is read: far above any real one, low enough that
    /// reading it cannot exhaust memory by itself.
    pub fn limit(self) -> u64 {
        const MIB: u64 = 1 << 20;
        match self {
            Kind::Scene => 16 * MIB,
            Kind::Mtl => 64 * MIB,
            Kind::Obj | Kind::Pbrt | Kind::Ply => 4096 * MIB,
            Kind::Exr => 8192 * MIB,
        }
    }

    /// The kind with its article: "a scene file", "an OBJ file".
    pub fn name(self) -> &'static str {
        match self {
            Kind::Scene => "a scene file",
            Kind::Obj => "an OBJ file",
            Kind::Pbrt => "a pbrt scene file",
            Kind::Ply => "a PLY file",
            Kind::Mtl => "an MTL file",
            Kind::Exr => "an EXR file",
        }
    }
}

/// A path as messages print it; an empty one would otherwise print as nothing at all.
pub fn show(path: &Path) -> String {
    if path.as_os_str().is_empty() {
        "(empty path)".into()
    } else {
        path.display().to_string()
    }
}

fn error(file: &Path, message: impl Into<String>) -> FileError {
    FileError {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

fn describe(kind: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_dir() {
        "a directory"
    } else if kind.is_fifo() {
        "a named pipe"
    } else if kind.is_char_device() || kind.is_block_device() {
        "a device"
    } else if kind.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// Checks that `path` is a regular file within the kind's size limit; returns its size.
pub fn check_input(path: &Path, kind: Kind) -> Result<u64, FileError> {
    if path.as_os_str().is_empty() {
        return Err(error(
            path,
            format!("the path is empty where {} should be", kind.name()),
        ));
    }
    // `metadata` follows symbolic links and, unlike opening, does not block on a FIFO.
    let meta = std::fs::metadata(path).map_err(|e| error(path, format!("cannot read: {e}")))?;
    check_metadata(path, kind, &meta)
}

fn check_metadata(path: &Path, kind: Kind, meta: &std::fs::Metadata) -> Result<u64, FileError> {
    if !meta.is_file() {
        return Err(error(
            path,
            format!(
                "is {}, not {} (only regular files are read)",
                describe(meta.file_type()),
                kind.name()
            ),
        ));
    }
    if meta.len() > kind.limit() {
        return Err(error(
            path,
            format!(
                "is {} bytes, more than the {} MiB {} may have",
                meta.len(),
                kind.limit() >> 20,
                kind.name()
            ),
        ));
    }
    Ok(meta.len())
}

/// Reads a whole input file after [`check_input`]; reads no more than the limit even if the
/// file grows meanwhile.
pub fn read(path: &Path, kind: Kind) -> Result<Vec<u8>, FileError> {
    check_input(path, kind)?;
    let file = File::open(path).map_err(|e| error(path, format!("cannot read: {e}")))?;
    // The file opened may not be the one checked (it was replaced in between).
    let meta = file
        .metadata()
        .map_err(|e| error(path, format!("cannot read: {e}")))?;
    let size = check_metadata(path, kind, &meta)?;
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(kind.limit() + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| error(path, format!("cannot read: {e}")))?;
    if bytes.len() as u64 > kind.limit() {
        return Err(error(
            path,
            format!(
                "grew past the {} MiB limit while being read",
                kind.limit() >> 20
            ),
        ));
    }
    Ok(bytes)
}

/// Reads a text input; invalid UTF-8 is an error naming the line.
pub fn read_text(path: &Path, kind: Kind) -> Result<String, FileError> {
    let bytes = read(path, kind)?;
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        error(path, format!("line {line}: not UTF-8 text"))
    })
}

/// At most `max` characters of `text` (one line of it), with an ellipsis when cut: long input
/// lines are quoted as a readable excerpt.
pub fn excerpt(text: &str, max: usize) -> String {
    let line = text.lines().next().unwrap_or("");
    let mut chars = line.chars();
    let head: String = chars.by_ref().take(max).collect();
    if chars.next().is_some() || line.len() < text.trim_end().len() {
        format!("{head}...")
    } else {
        head
    }
}

/// How many characters of a piece of input a message quotes.
pub const SNIPPET: usize = 64;

/// `text` as a message quotes it: whole when short, else its first [`SNIPPET`] characters, an
/// ellipsis and its full length, so a huge token or line never floods the terminal.
pub fn snippet(text: &str) -> Cow<'_, str> {
    match text.char_indices().nth(SNIPPET) {
        None => Cow::Borrowed(text),
        Some((cut, _)) => Cow::Owned(format!("{}... ({} bytes)", &text[..cut], text.len())),
    }
}

/// Shortens every line of a message to `max` characters (parsers quote whole input lines).
pub fn shorten_lines(message: &str, max: usize) -> String {
    message
        .lines()
        .map(|l| excerpt(l, max))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The path with its directory resolved, whether or not the file itself exists yet, so that
/// two spellings of one file compare equal.
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(dir).ok()?.join(path.file_name()?))
}

/// Checks that `output` can be written: a file name in an existing, writable directory, not a
/// directory, and none of `inputs` (which writing would destroy).
pub fn check_output(output: &Path, inputs: &[PathBuf]) -> Result<(), FileError> {
    let fail = |message: String| Err(error(output, message));
    if output.as_os_str().is_empty() {
        return fail("no output named (the path is empty)".into());
    }
    let Some(name) = output.file_name() else {
        return fail("does not name a file".into());
    };
    if output.is_dir() {
        return fail("is a directory; name a file in it".into());
    }
    if let Ok(meta) = std::fs::metadata(output) {
        if !meta.is_file() {
            return fail(format!(
                "is {}; the output must be a regular file",
                describe(meta.file_type())
            ));
        }
    }
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return fail(format!("the directory {} does not exist", show(dir)));
    }
    let target = resolved(output);
    for input in inputs {
        if target.is_some() && resolved(input) == target {
            return fail(format!(
                "is one of the render's inputs ({}); writing would destroy it",
                show(input)
            ));
        }
    }
    // A probe, where checking permission bits would miss read-only mounts and /proc.
    let probe = dir.join(format!(
        ".{}.probe-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    match File::create(&probe) {
        Ok(_) => {
            // Best effort: a probe left behind is harmless and named after the output.
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => fail(format!("cannot write into {}: {e}", show(dir))),
    }
}

/// The locks this process holds, by resolved output path: taking one twice in a process (a
/// render's early check, then its job) must not refuse itself, as a second `flock` on a new
/// descriptor would.
static HELD: Mutex<Vec<Held>> = Mutex::new(Vec::new());

/// One output's lock: the locked sidecar file and how many [`OutputLock`]s use it.
struct Held {
    output: PathBuf,
    sidecar: PathBuf,
    /// Open while the lock is held: closing it releases the lock.
    file: File,
    users: usize,
}

fn held() -> MutexGuard<'static, Vec<Held>> {
    // The list stays consistent whatever panicked while it was locked.
    HELD.lock().unwrap_or_else(|e| e.into_inner())
}

/// The file that locks `output`: `.NAME.lock` beside it. Outputs are replaced by a rename, so
/// a lock on the output's own inode would not outlive the first write.
fn sidecar(output: &Path) -> Option<PathBuf> {
    let name = output.file_name()?;
    Some(output.with_file_name(format!(".{}.lock", name.to_string_lossy())))
}

/// The process named in a held lock file; written just after the lock is taken, so an empty
/// file is read again once.
fn holder(file: &File) -> String {
    for _ in 0..2 {
        let mut text = String::new();
        let _ = file.take(32).read_to_string(&mut text);
        if let Ok(pid) = text.trim().parse::<u32>() {
            return format!("pid {pid}");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    "pid unknown".into()
}

/// Takes the advisory lock on `output`'s sidecar, or says which process holds it.
fn acquire(output: &Path, sidecar: &Path) -> Result<File, FileError> {
    use std::os::unix::fs::MetadataExt;
    let fail = |e: std::io::Error| error(output, format!("cannot lock {}: {e}", show(sidecar)));
    // A holder removes its lock file as it ends; a lock taken on a file unlinked meanwhile
    // locks nothing anyone else opens, so the path must still name the locked file.
    for _ in 0..16 {
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(sidecar)
            .map_err(fail)?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                return Err(error(
                    output,
                    format!(
                        "is being written by another vmerge process ({}, lock file {}); wait \
                         for it to end or write elsewhere",
                        holder(&file),
                        show(sidecar)
                    ),
                ))
            }
            Err(TryLockError::Error(e)) => return Err(fail(e)),
        }
        let locked = file.metadata().map_err(fail)?;
        let same = std::fs::metadata(sidecar)
            .is_ok_and(|now| now.dev() == locked.dev() && now.ino() == locked.ino());
        if same {
            file.set_len(0).map_err(fail)?;
            write!(file, "{}", std::process::id()).map_err(fail)?;
            return Ok(file);
        }
    }
    Err(error(
        output,
        format!("cannot lock {}: it keeps being replaced", show(sidecar)),
    ))
}

/// Holds the lock on `output` for this process without a guard, until an [`OutputLock`] on it
/// is taken and dropped (or the process ends): a check before any work reserves the output
/// for the job that follows.
pub fn hold_output(output: &Path) -> Result<(), FileError> {
    take(output, 0).map(|_| ())
}

/// An advisory lock (`flock`) on an output while it is written, so that a second process
/// writing the same file (a `render`, `continue` or `merge`) refuses at once instead of
/// overwriting the first one's work. Released, and its lock file removed, when the last
/// guard of the process on that output drops.
#[derive(Debug)]
pub struct OutputLock {
    output: PathBuf,
}

/// Locks `output` against other processes; within this process the lock is shared.
pub fn lock_output(output: &Path) -> Result<OutputLock, FileError> {
    take(output, 1).map(|output| OutputLock { output })
}

/// Takes or shares the lock on `output`, counting `users` more guards of it; returns the key
/// the guards name it by.
fn take(output: &Path, users: usize) -> Result<PathBuf, FileError> {
    // Every spelling of the output (a link included) locks the same file.
    let key = resolved(output).unwrap_or_else(|| output.to_path_buf());
    let Some(sidecar) = sidecar(&key) else {
        return Err(error(output, "does not name a file"));
    };
    let mut held = held();
    if let Some(h) = held.iter_mut().find(|h| h.output == key) {
        h.users += users;
    } else {
        let file = acquire(output, &sidecar)?;
        held.push(Held {
            output: key.clone(),
            sidecar,
            file,
            users,
        });
    }
    Ok(key)
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        let mut held = held();
        let Some(i) = held.iter().position(|h| h.output == self.output) else {
            return;
        };
        held[i].users -= 1;
        if held[i].users == 0 {
            let h = held.swap_remove(i);
            // Removed while still locked, so whoever opened it meanwhile sees it gone and
            // opens a new one; best effort: a lock file left behind only costs a name.
            let _ = std::fs::remove_file(&h.sidecar);
            drop(h.file);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excerpts_cut_long_lines() {
        assert_eq!(excerpt("short", 10), "short");
        assert_eq!(
            excerpt(&"x".repeat(50), 10),
            format!("{}...", "x".repeat(10))
        );
        assert_eq!(excerpt("one\ntwo", 10), "one...");
    }

    #[test]
    fn snippets_cut_on_a_char_boundary_and_give_the_length() {
        assert_eq!(snippet("short"), "short");
        let exact = "y".repeat(SNIPPET);
        assert_eq!(snippet(&exact), exact);
        let long = "\u{e9}".repeat(1000);
        assert_eq!(
            snippet(&long),
            format!("{}... (2000 bytes)", "\u{e9}".repeat(SNIPPET))
        );
    }

    #[test]
    fn only_regular_files_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let err = read(dir.path(), Kind::Scene).unwrap_err();
        assert!(err.message.contains("a directory"), "{err}");
        let err = read(Path::new("/dev/zero"), Kind::Mtl).unwrap_err();
        assert!(err.message.contains("a device"), "{err}");
        let err = read(Path::new(""), Kind::Obj).unwrap_err();
        assert!(err.to_string().starts_with("(empty path)"), "{err}");
    }

    #[test]
    fn outputs_must_not_be_inputs_or_directories() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("scene.toml");
        std::fs::write(&input, "").unwrap();
        let again = dir.path().join(".").join("scene.toml");
        assert!(check_output(&again, std::slice::from_ref(&input)).is_err());
        assert!(check_output(dir.path(), &[]).is_err());
        assert!(check_output(&dir.path().join("missing/out.exr"), &[]).is_err());
        assert!(check_output(&dir.path().join("out.exr"), &[input]).is_ok());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn outputs_lock_once_per_process_and_refuse_another_holder() {
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("out.exr");
        let sidecar = dir.path().join(".out.exr.lock");
        // A lock file left by a process that ended locks nothing.
        std::fs::write(&sidecar, "999999999").unwrap();
        hold_output(&output).unwrap();
        let first = lock_output(&output).unwrap();
        let second = lock_output(&dir.path().join(".").join("out.exr")).unwrap();
        assert_eq!(
            std::fs::read_to_string(&sidecar).unwrap(),
            std::process::id().to_string()
        );
        drop(first);
        assert!(sidecar.exists(), "released while still in use");
        drop(second);
        assert!(!sidecar.exists());

        // Another holder: a lock on a description of its own, as another process has.
        let other = File::create(&sidecar).unwrap();
        other.lock().unwrap();
        write!(&other, "4242").unwrap();
        let err = lock_output(&output).unwrap_err();
        assert!(err.message.contains("pid 4242"), "{err}");
        assert!(err.to_string().starts_with(&show(&output)), "{err}");
    }
}
