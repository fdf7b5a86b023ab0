//! Discrete distributions over weighted items (light selection by power) and piecewise-constant
//! 2D densities over cells (an environment image's texels).

/// A piecewise-constant distribution over `n` items, sampled by inverting its CDF.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    weights: Vec<f32>,
    cdf: Vec<f64>,
    total: f64,
    /// 1 / `total`: a probability is then a multiply, where a division (three times the
    /// latency) held up everything that weighs a sample.
    inv_total: f64,
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
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        Some(Distribution1D {
            weights,
            cdf,
            total,
            inv_total: 1.0 / total,
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
        (self.weights[i] as f64 * self.inv_total) as f32
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

    /// [`Distribution1D::sample`] that also returns where in the item's CDF step `u` fell, in
    /// [0, 1): a second uniform number for the position inside the item (pbrt's
    /// SampleContinuous).
    pub fn sample_continuous(&self, u: f32) -> (usize, f32, f32) {
        let (i, p) = self.sample(u);
        let target = u as f64 * self.total;
        let offset = (target - self.cdf[i]) / self.weights[i] as f64;
        (i, (offset as f32).clamp(0.0, 1.0 - f32::EPSILON / 2.0), p)
    }

    /// Bytes held (weights and CDF).
    pub fn bytes(&self) -> usize {
        self.weights.len() * std::mem::size_of::<f32>()
            + self.cdf.len() * std::mem::size_of::<f64>()
    }
}

/// A piecewise-constant density over a grid of `width` x `height` cells, sampled by its
/// marginal over rows and the conditional within the chosen row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    marginal: Distribution1D,
    /// One per row; `None` for rows of zero weight, which the marginal never picks.
    rows: Vec<Option<Distribution1D>>,
}

impl Distribution2D {
    /// `weights` row by row; `None` when they do not sum to a positive finite number.
    pub fn new(width: usize, weights: &[f32]) -> Option<Self> {
        if width == 0 || !weights.len().is_multiple_of(width) {
            return None;
        }
        let rows: Vec<Option<Distribution1D>> = weights
            .chunks_exact(width)
            .map(|row| Distribution1D::new(row.to_vec()))
            .collect();
        let row_weights = weights
            .chunks_exact(width)
            .map(|row| row.iter().map(|&w| w as f64).sum::<f64>() as f32)
            .collect();
        Some(Distribution2D {
            marginal: Distribution1D::new(row_weights)?,
            rows,
        })
    }

    /// A cell and a point in it for `u`: `(x, y)` continuous in `[0, width) x [0, height)`,
    /// and the probability of the cell.
    pub fn sample(&self, u: [f32; 2]) -> ([f32; 2], f32) {
        let (y, dy, py) = self.marginal.sample_continuous(u[1]);
        let row = self.rows[y]
            .as_ref()
            .expect("the marginal picks rows of positive weight only");
        let (x, dx, px) = row.sample_continuous(u[0]);
        ([x as f32 + dx, y as f32 + dy], py * px)
    }

    /// Probability of the cell `(x, y)`.
    pub fn pmf(&self, x: usize, y: usize) -> f32 {
        match &self.rows[y] {
            Some(row) => self.marginal.pmf(y) * row.pmf(x),
            None => 0.0,
        }
    }

    /// Bytes held by the marginal and the rows.
    pub fn bytes(&self) -> usize {
        self.marginal.bytes()
            + self
                .rows
                .iter()
                .flatten()
                .map(Distribution1D::bytes)
                .sum::<usize>()
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

    #[test]
    fn continuous_samples_stay_in_their_cell() {
        let d = Distribution2D::new(2, &[1.0, 0.0, 0.0, 3.0]).unwrap();
        let ([x, y], p) = d.sample([0.5, 0.9]);
        assert!(
            (1.0..2.0).contains(&x) && (1.0..2.0).contains(&y),
            "{x} {y}"
        );
        assert!((p - 0.75).abs() < 1e-6);
        assert_eq!(d.pmf(1, 0), 0.0);
        assert!((d.pmf(0, 0) - 0.25).abs() < 1e-6);
        let ([x, y], _) = d.sample([0.3, 0.1]);
        assert!(x < 1.0 && y < 1.0 && (y - 0.4).abs() < 1e-5, "{x} {y}");
    }
}
