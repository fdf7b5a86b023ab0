//! Discrete distributions over weighted items (light selection by power).

/// A piecewise-constant distribution over `n` items, sampled by inverting its CDF.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    weights: Vec<f32>,
    cdf: Vec<f64>,
    total: f64,
}

impl Distribution1D {
    /// `None` when the weights do not sum to a positive finite number.
    pub fn new(weights: Vec<f32>) -> Option<Self> {
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut total = 0.0f64;
        cdf.push(0.0);
        for &w in &weights {
            if !(w >= 0.0 && w.is_finite()) {
                return None;
            }
            total += w as f64;
            cdf.push(total);
        }
        (total > 0.0 && total.is_finite()).then_some(Distribution1D {
            weights,
            cdf,
            total,
        })
    }

    pub fn len(&self) -> usize {
        self.weights.len()
    }

    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// Probability of item `i`.
    pub fn pmf(&self, i: usize) -> f32 {
        (self.weights[i] as f64 / self.total) as f32
    }

    /// Picks an item for `u` in [0, 1); returns it and its probability. Never returns an item
    /// of zero weight.
    pub fn sample(&self, u: f32) -> (usize, f32) {
        let target = u as f64 * self.total;
        // First index whose upper CDF bound exceeds the target.
        let mut i = self.cdf[1..].partition_point(|&c| c <= target);
        i = i.min(self.weights.len() - 1);
        while self.weights[i] == 0.0 && i > 0 {
            i -= 1;
        }
        (i, self.pmf(i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_follows_weights() {
        let d = Distribution1D::new(vec![1.0, 0.0, 3.0]).unwrap();
        assert_eq!(d.sample(0.0).0, 0);
        assert_eq!(d.sample(0.2499).0, 0);
        assert_eq!(d.sample(0.25).0, 2);
        assert_eq!(d.sample(0.9999).0, 2);
        assert!((d.pmf(2) - 0.75).abs() < 1e-7);
        assert!(Distribution1D::new(vec![0.0]).is_none());
        assert!(Distribution1D::new(vec![f32::NAN]).is_none());
    }
}
