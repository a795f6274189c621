//! The twin's figure as a smooth function of the free values (issue 46; docs/calibration.md): a
//! quadratic in the values scaled to [0, 1], fitted by weighted least squares over the draws, so
//! that every draw's trials inform the figure everywhere (a handful of draws of 20 trials each
//! would leave each draw's own figure too noisy to weigh it by). A success rate is fitted on its
//! logit, each draw weighted by the inverse of its binomial variance there; a mean on its value,
//! weighted by its trials over its variance. The fit's covariance, scaled up by the residuals'
//! excess over what the trials explain (never down), gives each prediction its standard error.

use super::targets::Figure;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// What the twin gave for one figure at one draw.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Simulated {
    /// `s` successes of `m` trials.
    Count { s: usize, m: usize },
    /// A mean over `m` trials with their standard deviation.
    Mean { mean: f64, std: f64, m: usize },
    /// The twin gave no such figure (no success to take a force from, no estimate to err).
    Missing,
}

impl Simulated {
    /// Whether this can be what the twin gave for `figure` (read back from a file): a count of
    /// at most its trials for a success rate; a finite mean with a finite, non-negative spread
    /// for the others; or nothing.
    pub fn fits(&self, figure: Figure) -> bool {
        match *self {
            Simulated::Count { s, m } => figure == Figure::Success && s <= m && m > 0,
            Simulated::Mean { mean, std, m } => {
                figure != Figure::Success
                    && mean.is_finite()
                    && std.is_finite()
                    && std >= 0.0
                    && m > 0
            }
            Simulated::Missing => true,
        }
    }
}

/// What the surrogate predicts at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prediction {
    /// A success rate: its logit and that logit's standard error.
    Rate { logit: f64, se: f64 },
    /// A mean: its value, its standard error, and the twin's spread of the figure over trials.
    Mean { mean: f64, se: f64, spread: f64 },
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Rate,
    Mean { spread: f64 },
}

/// A fitted surrogate of one figure.
#[derive(Clone, Debug)]
pub struct Surrogate {
    kind: Kind,
    quadratic: bool,
    coef: DVector<f64>,
    /// Covariance of the coefficients (scaled by the residuals' excess).
    cov: DMatrix<f64>,
}

/// The smallest spread a mean's weight uses, in the figure's unit (a figure every trial gives
/// alike still has rounding).
const MIN_SPREAD: f64 = 1e-3;

/// The regressors at `u`: 1, each value, and with `quadratic` every product of two.
fn features(u: &[f64], quadratic: bool) -> Vec<f64> {
    let mut x = vec![1.0];
    x.extend_from_slice(u);
    if quadratic {
        for i in 0..u.len() {
            for j in i..u.len() {
                x.push(u[i] * u[j]);
            }
        }
    }
    x
}

impl Surrogate {
    /// Fits the figure `sims[i]` the twin gave at the scaled values `u[i]` (draws where it gave
    /// none are left out); quadratic when the draws are enough to spare two, else linear, else
    /// constant; `None` when no draw gave the figure.
    pub fn fit(u: &[Vec<f64>], sims: &[Simulated]) -> Option<Self> {
        let rows: Vec<(&[f64], f64, f64)> = (u.iter().zip(sims))
            .filter_map(|(u, s)| Some((u.as_slice(), observation(s)?)))
            .map(|(u, (y, w))| (u, y, w))
            .collect();
        let kind = match sims.iter().find(|s| !matches!(s, Simulated::Missing))? {
            Simulated::Count { .. } => Kind::Rate,
            _ => Kind::Mean {
                spread: pooled_spread(sims),
            },
        };
        let d = u.first().map_or(0, Vec::len);
        let quadratic_terms = 1 + 2 * d + d * d.saturating_sub(1) / 2;
        let degrees = [(true, quadratic_terms), (false, 1 + d)];
        for (quadratic, p) in degrees {
            if rows.len() >= p + 2
                && let Some(s) = Self::least_squares(&rows, quadratic, kind)
            {
                return Some(s);
            }
        }
        Self::constant(&rows, kind)
    }

    fn least_squares(rows: &[(&[f64], f64, f64)], quadratic: bool, kind: Kind) -> Option<Self> {
        let p = features(rows[0].0, quadratic).len();
        let x = DMatrix::from_fn(rows.len(), p, |i, j| features(rows[i].0, quadratic)[j]);
        let w = DVector::from_iterator(rows.len(), rows.iter().map(|r| r.2));
        let y = DVector::from_iterator(rows.len(), rows.iter().map(|r| r.1));
        let xtw = x.transpose() * DMatrix::from_diagonal(&w);
        let normal = (&xtw * &x).cholesky()?;
        let coef = normal.solve(&(&xtw * &y));
        let residual = &y - &x * &coef;
        let rss: f64 = residual.iter().zip(w.iter()).map(|(r, w)| w * r * r).sum();
        let excess = (rss / (rows.len() - p) as f64).max(1.0);
        Some(Surrogate {
            kind,
            quadratic,
            coef,
            cov: normal.inverse() * excess,
        })
    }

    /// The weighted mean, with its standard error.
    fn constant(rows: &[(&[f64], f64, f64)], kind: Kind) -> Option<Self> {
        let total: f64 = rows.iter().map(|r| r.2).sum();
        if rows.is_empty() || total <= 0.0 {
            return None;
        }
        let mean = rows.iter().map(|r| r.1 * r.2).sum::<f64>() / total;
        let d = rows[0].0.len();
        let mut coef = DVector::zeros(1 + d);
        coef[0] = mean;
        let mut cov = DMatrix::zeros(1 + d, 1 + d);
        cov[(0, 0)] = 1.0 / total;
        Some(Surrogate {
            kind,
            quadratic: false,
            coef,
            cov,
        })
    }

    /// The prediction at the scaled values `u`.
    pub fn at(&self, u: &[f64]) -> Prediction {
        let x = DVector::from_vec(features(u, self.quadratic));
        let value = x.dot(&self.coef);
        let se = (x.dot(&(&self.cov * &x))).max(0.0).sqrt();
        match self.kind {
            Kind::Rate => Prediction::Rate { logit: value, se },
            Kind::Mean { spread } => Prediction::Mean {
                mean: value,
                se,
                spread,
            },
        }
    }
}

/// A draw's figure as a regression observation: value and weight (inverse variance).
fn observation(s: &Simulated) -> Option<(f64, f64)> {
    match *s {
        Simulated::Count { s, m } if m > 0 => {
            let p = (s as f64 + 0.5) / (m as f64 + 1.0);
            Some(((p / (1.0 - p)).ln(), (m as f64 + 1.0) * p * (1.0 - p)))
        }
        Simulated::Mean { mean, std, m } if m > 0 => {
            Some((mean, m as f64 / std.max(MIN_SPREAD).powi(2)))
        }
        _ => None,
    }
}

/// The twin's spread of a mean figure over trials, pooled over the draws.
fn pooled_spread(sims: &[Simulated]) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for s in sims {
        if let Simulated::Mean { std, m, .. } = *s {
            sum += m as f64 * std * std;
            n += m as f64;
        }
    }
    if n > 0.0 { (sum / n).sqrt() } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_linear_rate_and_a_quadratic_mean_come_back() {
        let u: Vec<Vec<f64>> = (0..9).map(|i| vec![i as f64 / 8.0]).collect();
        let rate: Vec<Simulated> = (u.iter())
            .map(|u| {
                let p = 1.0 / (1.0 + (-(2.0 * u[0] - 1.0)).exp());
                Simulated::Count {
                    s: (p * 10_000.0).round() as usize,
                    m: 10_000,
                }
            })
            .collect();
        let s = Surrogate::fit(&u, &rate).unwrap();
        let Prediction::Rate { logit, se } = s.at(&[0.75]) else {
            panic!()
        };
        assert!((logit - 0.5).abs() < 0.01 && se < 0.05, "{logit} {se}");
        let mean: Vec<Simulated> = (u.iter())
            .map(|u| Simulated::Mean {
                mean: 3.0 + (u[0] - 0.5).powi(2),
                std: 0.1,
                m: 100,
            })
            .collect();
        let s = Surrogate::fit(&u, &mean).unwrap();
        let Prediction::Mean { mean, spread, .. } = s.at(&[0.5]) else {
            panic!()
        };
        assert!((mean - 3.0).abs() < 1e-9 && (spread - 0.1).abs() < 1e-12);
        assert!(Surrogate::fit(&u, &vec![Simulated::Missing; 9]).is_none());
    }
}
