//! Linear least squares, `min |A x - y|`, by Householder QR: the one solver
//! of the crate (sinusoid fits of partial ranges and spectra, the
//! partial-range table fit, model-gap's effect fits).
//!
//! No normal equations: QR keeps the conditioning of `A` instead of squaring
//! it, which matters for the nearly collinear columns of a short arc. A
//! column whose part independent of the earlier columns is too small to
//! resolve is reported by its index; what "too small" means is the caller's
//! (an absolute floor, or relative to the column's own norm).

/// The QR factorisation of a design matrix given by its columns, to solve for
/// any number of right-hand sides.
#[derive(Debug, Clone, PartialEq)]
pub struct Qr {
    rows: usize,
    /// Householder vectors: `v[j]` acts on rows `j..`.
    v: Vec<Vec<f64>>,
    /// `R`, upper triangular, row-major `p x p`.
    r: Vec<f64>,
}

/// The Euclidean norm of each column.
pub fn column_norms<C: AsRef<[f64]>>(columns: &[C]) -> Vec<f64> {
    columns.iter().map(|c| c.as_ref().iter().map(|v| v * v).sum::<f64>().sqrt()).collect()
}

impl Qr {
    /// Factorise the columns (all of the same length `n >= columns.len()`).
    /// Column `j` is unresolvable, and its index the error, when the norm of
    /// its part independent of columns `0..j` is NaN or at most `min_norm(j)`;
    /// with fewer rows than columns, the first column past the rows is.
    pub fn new(mut columns: Vec<Vec<f64>>, min_norm: impl Fn(usize) -> f64) -> Result<Self, usize> {
        let p = columns.len();
        let n = columns.first().map_or(0, Vec::len);
        if n < p {
            return Err(n);
        }
        let mut v = Vec::with_capacity(p);
        let mut r = vec![0.0; p * p];
        for j in 0..p {
            let norm = columns[j][j..].iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm.is_nan() || norm <= min_norm(j) {
                return Err(j);
            }
            let alpha = if columns[j][j] > 0.0 { -norm } else { norm };
            // Column `j` is not needed past here: its rows `j..` become the
            // Householder vector in place (no second copy of the matrix).
            let mut h = std::mem::take(&mut columns[j]);
            h.drain(..j);
            h[0] -= alpha;
            let hh: f64 = h.iter().map(|x| x * x).sum();
            // Apply I - 2 h h^T / (h^T h) to the later columns (column j becomes alpha e_0).
            for (c, col) in columns.iter_mut().enumerate().skip(j + 1) {
                reflect(&mut col[j..], &h, hh);
                r[j * p + c] = col[j];
            }
            r[j * p + j] = alpha;
            v.push(h);
        }
        Ok(Qr { rows: n, v, r })
    }

    /// Rows of the design matrix.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Columns (unknowns).
    pub fn cols(&self) -> usize {
        self.v.len()
    }

    /// `R` (row-major, `p x p`, upper triangular): `A = Q R`.
    pub fn r(&self, i: usize, j: usize) -> f64 {
        self.r[i * self.cols() + j]
    }

    /// The least-squares coefficients for `y` (of length [`Qr::rows`]) and
    /// the residual sum of squares.
    pub fn solve(&self, y: &[f64]) -> (Vec<f64>, f64) {
        assert_eq!(y.len(), self.rows, "one value per row");
        let p = self.cols();
        let mut qy = y.to_vec();
        for (j, h) in self.v.iter().enumerate() {
            let hh: f64 = h.iter().map(|x| x * x).sum();
            reflect(&mut qy[j..], h, hh);
        }
        let mut x = vec![0.0; p];
        for i in (0..p).rev() {
            let s: f64 = (i + 1..p).map(|k| self.r(i, k) * x[k]).sum();
            x[i] = (qy[i] - s) / self.r(i, i);
        }
        (x, qy[p..].iter().map(|v| v * v).sum())
    }

    /// The diagonal of `(A^T A)^-1`: each coefficient's variance per unit
    /// noise variance.
    pub fn unit_var(&self) -> Vec<f64> {
        let p = self.cols();
        // (A^T A)^-1 = R^-1 R^-T: its diagonal is the squared row norms of R^-1.
        let mut rinv = vec![0.0; p * p];
        for c in 0..p {
            for i in (0..=c).rev() {
                let e = if i == c { 1.0 } else { 0.0 };
                let s: f64 = (i + 1..=c).map(|k| self.r(i, k) * rinv[k * p + c]).sum();
                rinv[i * p + c] = (e - s) / self.r(i, i);
            }
        }
        (0..p).map(|i| (i..p).map(|c| rinv[i * p + c].powi(2)).sum()).collect()
    }

    /// `|R^-T a|`: the standard deviation, per unit noise, of the fitted
    /// value at a point whose basis values are `a` (its leverage).
    pub fn leverage(&self, a: &[f64]) -> f64 {
        let p = self.cols();
        let mut z = vec![0.0; p];
        for i in 0..p {
            let s: f64 = (0..i).map(|k| self.r(k, i) * z[k]).sum();
            z[i] = (a[i] - s) / self.r(i, i);
        }
        z.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// Apply the reflection `I - 2 h h^T / hh` to `x`.
fn reflect(x: &mut [f64], h: &[f64], hh: f64) {
    let f = 2.0 * x.iter().zip(h).map(|(a, b)| a * b).sum::<f64>() / hh;
    x.iter_mut().zip(h).for_each(|(a, b)| *a -= f * b);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_detects_collinear_columns() {
        let x: Vec<f64> = (0..50).map(|i| i as f64 / 10.0).collect();
        let ones = vec![1.0; 50];
        let sq: Vec<f64> = x.iter().map(|v| v * v).collect();
        let y: Vec<f64> = x.iter().map(|v| 2.0 - 0.5 * v + 0.25 * v * v).collect();
        let qr = Qr::new(vec![ones.clone(), x.clone(), sq], |_| 0.0).unwrap();
        let (c, ss) = qr.solve(&y);
        assert!((c[0] - 2.0).abs() < 1e-12 && (c[1] + 0.5).abs() < 1e-12 && (c[2] - 0.25).abs() < 1e-12, "{c:?}");
        assert!(ss < 1e-24);
        // The variance of the mean of n samples is 1/n; its leverage sqrt(1/n).
        let mean = Qr::new(vec![ones.clone()], |_| 0.0).unwrap();
        assert!((mean.unit_var()[0] - 1.0 / 50.0).abs() < 1e-15);
        assert!((mean.leverage(&[1.0]) - (1.0f64 / 50.0).sqrt()).abs() < 1e-15);
        let twice: Vec<f64> = x.iter().map(|v| 2.0 * v).collect();
        let norms = column_norms(&[ones.clone(), x.clone(), twice.clone()]);
        assert_eq!(Qr::new(vec![ones.clone(), x, twice], |j| 1e-6 * norms[j]).unwrap_err(), 2);
        assert_eq!(Qr::new(vec![vec![1.0, 2.0]; 3], |_| 0.0).unwrap_err(), 2, "2 rows hold 2 unknowns");
    }

    #[test]
    fn residual_is_what_the_fit_leaves() {
        // y = 1 + t + a residual orthogonal to both columns.
        let t = [-1.0, 0.0, 1.0];
        let y = [0.0 + 1.0, 1.0 - 2.0, 2.0 + 1.0];
        let qr = Qr::new(vec![vec![1.0; 3], t.to_vec()], |_| 0.0).unwrap();
        let (c, ss) = qr.solve(&y);
        assert!((c[0] - 1.0).abs() < 1e-15 && (c[1] - 1.0).abs() < 1e-15, "{c:?}");
        assert!((ss - 6.0).abs() < 1e-12, "{ss}");
    }
}
