//! The inference of `pegtwin calibrate` (issue 46; docs/calibration.md): the posterior of the
//! free values over a dense Latin hypercube of their uniform prior, each point weighted by the
//! likelihood of the fitted figures given the twin's figures there ([`super::surrogate`]), and
//! the posterior predictive interval of every figure, fitted or held out.
//!
//! Likelihoods. A success count: `k` of `n` measured is binomial in the twin's success rate,
//! whose logit the surrogate knows to a standard error (integrated by Gauss-Hermite). A mean:
//! normal about the twin's, with the surrogate's variance plus a run's noise, `spread^2 / n`, the
//! spread over trials the larger of the measured one and the twin's (a synthetic likelihood's
//! spread comes from the simulations; a measured spread that happens to be small, as one of a
//! heavy-tailed figure over few trials can be, does not make the fit over-confident).

use super::surrogate::Prediction;
use super::targets::Measured;
use serde::{Deserialize, Serialize};

/// ln of the binomial coefficient C(n, k).
fn ln_choose(n: usize, k: usize) -> f64 {
    let (n, k) = (n as f64, k as f64);
    libm::lgamma(n + 1.0) - libm::lgamma(k + 1.0) - libm::lgamma(n - k + 1.0)
}

/// ln(1 + e^x), without overflow.
fn softplus(x: f64) -> f64 {
    x.max(0.0) + (-x.abs()).exp().ln_1p()
}

/// ln P(k of n) for a success rate of logit `logit`.
fn ln_binomial(k: usize, n: usize, logit: f64) -> f64 {
    ln_choose(n, k) - k as f64 * softplus(-logit) - (n - k) as f64 * softplus(logit)
}

/// Nodes and weights of 9-point Gauss-Hermite quadrature (weight e^(-x^2); the weights sum to
/// sqrt(pi)).
const GAUSS_HERMITE: [(f64, f64); 9] = [
    (0.0, 0.720_235_215_606_051),
    (0.723_551_018_752_837_6, 0.432_651_559_002_555_8),
    (-0.723_551_018_752_837_6, 0.432_651_559_002_555_8),
    (1.468_553_289_216_668, 0.088_474_527_394_376_6),
    (-1.468_553_289_216_668, 0.088_474_527_394_376_6),
    (2.266_580_584_531_843, 0.004_943_624_275_536_9),
    (-2.266_580_584_531_843, 0.004_943_624_275_536_9),
    (3.190_993_201_781_528, 0.000_039_606_977_263_3),
    (-3.190_993_201_781_528, 0.000_039_606_977_263_3),
];

/// P(k of n) when the rate's logit is normal (`logit`, `se`).
fn binomial_over_logit(k: usize, n: usize, logit: f64, se: f64) -> f64 {
    let sum: f64 = GAUSS_HERMITE
        .iter()
        .map(|(x, w)| w * ln_binomial(k, n, logit + std::f64::consts::SQRT_2 * se * x).exp())
        .sum();
    sum / std::f64::consts::PI.sqrt()
}

fn ln_normal(x: f64, mu: f64, sigma: f64) -> f64 {
    let z = (x - mu) / sigma;
    -0.5 * z * z - sigma.ln() - 0.5 * (2.0 * std::f64::consts::PI).ln()
}

fn normal_cdf(x: f64, mu: f64, sigma: f64) -> f64 {
    0.5 * libm::erfc(-(x - mu) / (sigma * std::f64::consts::SQRT_2))
}

/// The smallest standard deviation a mean's comparison uses, in the figure's unit.
const MIN_SIGMA: f64 = 1e-9;

/// ln of the likelihood of `measured` given the twin's prediction (minus infinity when their
/// kinds differ).
pub fn ln_likelihood(measured: &Measured, predicted: &Prediction) -> f64 {
    match (*measured, *predicted) {
        (Measured::Count { k, n }, Prediction::Rate { logit, se }) => {
            binomial_over_logit(k, n, logit, se).ln()
        }
        (
            Measured::Mean { mean, std, n },
            Prediction::Mean {
                mean: mu,
                se,
                spread,
            },
        ) => {
            let noise = std.max(spread);
            let sigma = (se * se + noise * noise / n as f64).sqrt().max(MIN_SIGMA);
            ln_normal(mean, mu, sigma)
        }
        _ => f64::NEG_INFINITY,
    }
}

/// Normalised weights from log weights (log-sum-exp); all zero when every draw is impossible.
pub fn normalise(ln_w: &[f64]) -> Vec<f64> {
    let top = ln_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return vec![0.0; ln_w.len()];
    }
    let w: Vec<f64> = ln_w.iter().map(|l| (l - top).exp()).collect();
    let sum: f64 = w.iter().sum();
    w.into_iter().map(|x| x / sum).collect()
}

/// The effective number of draws behind normalised weights (Kish): 1 / sum w^2.
pub fn effective_draws(w: &[f64]) -> f64 {
    let sq: f64 = w.iter().map(|x| x * x).sum();
    if sq > 0.0 { 1.0 / sq } else { 0.0 }
}

/// The weighted `q`-quantile of `values` (the smallest value whose cumulative weight reaches q).
pub fn weighted_quantile(values: &[f64], w: &[f64], q: f64) -> f64 {
    let mut order: Vec<usize> = (0..values.len()).filter(|&i| w[i] > 0.0).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut cum = 0.0;
    for &i in &order {
        cum += w[i];
        if cum >= q - 1e-12 {
            return values[i];
        }
    }
    order.last().map_or(f64::NAN, |&i| values[i])
}

/// A figure's posterior predictive: the 90 % interval of what a real run of the measured size
/// would give, and how far into its tails the measured value lies.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Predictive {
    /// 5 % and 95 % quantiles: a success rate (0-1) or the figure's mean.
    pub interval: [f64; 2],
    /// The predictive's median.
    pub median: f64,
    /// Two-sided tail probability of the measured value (1: at the median; small: far out).
    pub tail: f64,
    pub inside: bool,
}

/// The posterior predictive of `measured` (a real run of the measured size) given the twin's
/// prediction at each point and the points' weights.
pub fn predictive(measured: &Measured, predicted: &[Prediction], w: &[f64]) -> Predictive {
    let parts: Vec<(f64, &Prediction)> = (w.iter().copied().zip(predicted))
        .filter(|(wi, _)| *wi > 0.0)
        .collect();
    match *measured {
        Measured::Count { k, n } => count_predictive(k, n, &parts),
        Measured::Mean { mean, n, .. } => mean_predictive(mean, n, &parts),
    }
}

/// A mixture of binomials over 0..=n successes.
fn count_predictive(k: usize, n: usize, parts: &[(f64, &Prediction)]) -> Predictive {
    let mut pmf = vec![0.0; n + 1];
    for (wi, p) in parts {
        if let Prediction::Rate { logit, se } = p {
            for (j, pj) in pmf.iter_mut().enumerate() {
                *pj += wi * binomial_over_logit(j, n, *logit, *se);
            }
        }
    }
    let cdf: Vec<f64> = pmf
        .iter()
        .scan(0.0, |c, p| {
            *c += p;
            Some(*c)
        })
        .collect();
    let at = |q: f64| cdf.iter().position(|&c| c >= q - 1e-12).unwrap_or(n);
    let (lo, mid, hi) = (at(0.05), at(0.5), at(0.95));
    let below = cdf[k];
    let above = 1.0 - if k == 0 { 0.0 } else { cdf[k - 1] };
    Predictive {
        interval: [lo as f64 / n as f64, hi as f64 / n as f64],
        median: mid as f64 / n as f64,
        tail: (2.0 * below.min(above)).min(1.0),
        inside: (lo..=hi).contains(&k),
    }
}

/// A mixture of normals (each point's mean, with its standard error and the spread a run of
/// `n` trials shows); quantiles by bisection on its distribution function.
fn mean_predictive(x: f64, n: usize, parts: &[(f64, &Prediction)]) -> Predictive {
    let normals: Vec<(f64, f64, f64)> = parts
        .iter()
        .filter_map(|(wi, p)| match **p {
            Prediction::Mean { mean, se, spread } => {
                let sigma = (se * se + spread * spread / n as f64).sqrt().max(MIN_SIGMA);
                Some((*wi, mean, sigma))
            }
            _ => None,
        })
        .collect();
    let cdf = |v: f64| -> f64 {
        normals
            .iter()
            .map(|(w, mu, s)| w * normal_cdf(v, *mu, *s))
            .sum()
    };
    let lo = normals
        .iter()
        .map(|(_, mu, s)| mu - 10.0 * s)
        .fold(f64::INFINITY, f64::min);
    let hi = normals
        .iter()
        .map(|(_, mu, s)| mu + 10.0 * s)
        .fold(f64::NEG_INFINITY, f64::max);
    let quantile = |q: f64| {
        let (mut a, mut b) = (lo, hi);
        for _ in 0..100 {
            let c = 0.5 * (a + b);
            if cdf(c) < q { a = c } else { b = c }
        }
        0.5 * (a + b)
    };
    let interval = [quantile(0.05), quantile(0.95)];
    let p = cdf(x);
    Predictive {
        interval,
        median: quantile(0.5),
        tail: (2.0 * p.min(1.0 - p)).min(1.0),
        inside: interval[0] <= x && x <= interval[1],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomial_over_a_logit_sums_to_one_and_widens_with_its_error() {
        for se in [0.0, 0.5] {
            let total: f64 = (0..=40).map(|k| binomial_over_logit(k, 40, 0.0, se)).sum();
            assert!((total - 1.0).abs() < 1e-6, "{total}");
        }
        assert!(binomial_over_logit(20, 40, 0.0, 0.5) < binomial_over_logit(20, 40, 0.0, 0.0));
    }

    #[test]
    fn weights_quantiles_and_predictive_intervals() {
        let w = normalise(&[0.0, f64::NEG_INFINITY, (3.0f64).ln()]);
        assert_eq!(w, vec![0.25, 0.0, 0.75]);
        assert!((effective_draws(&w) - 1.6).abs() < 1e-12);
        assert_eq!(weighted_quantile(&[1.0, 5.0, 2.0], &w, 0.05), 1.0);
        assert_eq!(weighted_quantile(&[1.0, 5.0, 2.0], &w, 0.5), 2.0);
        let half = [Prediction::Rate {
            logit: 0.0,
            se: 0.0,
        }];
        let p = predictive(&Measured::Count { k: 50, n: 100 }, &half, &[1.0]);
        assert!(p.inside && (p.median - 0.5).abs() < 0.011, "{p:?}");
        assert!((p.interval[0] - 0.42).abs() < 0.015 && (p.interval[1] - 0.58).abs() < 0.015);
        let far = predictive(&Measured::Count { k: 5, n: 100 }, &half, &[1.0]);
        assert!(!far.inside && far.tail < 1e-6, "{far:?}");
        let mean = [Prediction::Mean {
            mean: 2.0,
            se: 0.0,
            spread: 1.0,
        }];
        let p = predictive(
            &Measured::Mean {
                mean: 2.1,
                std: 1.0,
                n: 100,
            },
            &mean,
            &[1.0],
        );
        assert!(
            (p.interval[1] - 2.0 - 0.1645).abs() < 1e-3 && p.inside,
            "{p:?}"
        );
    }
}
