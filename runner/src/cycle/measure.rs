//! Metrics of an output over one cycle, from its values at evenly spaced times of the
//! period: for a smooth periodic output the periodic trapezoidal rule (mean, RMS) and the
//! discrete Fourier sum (a harmonic's amplitude) are exact to rounding once the samples
//! resolve its harmonics, and an extreme is found between samples as a transient's is
//! ([`crate::metrics::refined`]), the samples wrapping round the period.

use crate::cycle_plan::{CycleKind, CycleMetric};
use crate::metrics::{refined, Extremes, Sample};

/// The signs whose extremes a metric is made of: +1 for the largest value, −1 for the
/// smallest.
pub fn signs(kind: CycleKind) -> &'static [f64] {
    match kind {
        CycleKind::Max => &[1.0],
        CycleKind::Min => &[-1.0],
        CycleKind::PeakAbs | CycleKind::PeakToPeak => &[1.0, -1.0],
        _ => &[],
    }
}

/// The sample where sign·x is largest over the cycle, and those either side of it (the
/// samples wrap round the period).
pub fn around(column: &[Sample], sign: f64) -> [usize; 3] {
    let m = column.len();
    let (i, _) = column
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, s)| {
            if sign * s.x > best.1 {
                (i, sign * s.x)
            } else {
                best
            }
        });
    [(i + m - 1) % m, i, (i + 1) % m]
}

/// The extreme of sign·x over the cycle, found as the metric asks.
fn extreme(column: &[Sample], period: f64, sign: f64, extremes: Extremes) -> f64 {
    let [left, at, right] = around(column, sign);
    let (mut a, b, mut c) = (column[left], column[at], column[right]);
    if extremes == Extremes::Sampled {
        return b.x;
    }
    // Round the period's ends, the neighbour lies a period away.
    if a.t > b.t {
        a.t -= period;
    }
    if c.t < b.t {
        c.t += period;
    }
    refined(sign, Some(a), b, Some(c))
}

pub fn metric(column: &[Sample], period: f64, metric: &CycleMetric) -> f64 {
    let m = column.len() as f64;
    let top = |sign| extreme(column, period, sign, metric.extremes);
    match metric.kind {
        CycleKind::Max => top(1.0),
        CycleKind::Min => top(-1.0),
        CycleKind::PeakAbs => top(1.0).max(-top(-1.0)),
        CycleKind::PeakToPeak => top(1.0) - top(-1.0),
        CycleKind::Mean => column.iter().map(|s| s.x).sum::<f64>() / m,
        CycleKind::Rms => (column.iter().map(|s| s.x * s.x).sum::<f64>() / m).sqrt(),
        CycleKind::Harmonic => {
            let (mut re, mut im) = (0.0, 0.0);
            for (j, s) in column.iter().enumerate() {
                let angle = std::f64::consts::TAU * (j as u64 * u64::from(metric.order)) as f64 / m;
                re += s.x * angle.cos();
                im -= s.x * angle.sin();
            }
            2.0 * re.hypot(im) / m
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metrics_of_a_known_signal() {
        let m = 2048;
        let tau = std::f64::consts::TAU;
        let signal = |s: f64| 1.5 + 2.0 * (tau * s + 0.3).cos() + 0.25 * (3.0 * tau * s).sin();
        let rate = |s: f64| -2.0 * tau * (tau * s + 0.3).sin() + 0.75 * tau * (3.0 * tau * s).cos();
        let column = |rates: bool| -> Vec<Sample> {
            (0..m)
                .map(|j| {
                    let t = j as f64 / m as f64;
                    Sample {
                        t,
                        x: signal(t),
                        rate: rates.then(|| rate(t)),
                    }
                })
                .collect()
        };
        let fine: Vec<f64> = (0..1_000_000).map(|j| signal(j as f64 / 1e6)).collect();
        let (max, min) = fine
            .iter()
            .fold((f64::MIN, f64::MAX), |(a, b), &v| (a.max(v), b.min(v)));
        let close = |a: f64, b: f64, tol: f64| assert!((a - b).abs() <= tol, "{a} vs {b}");
        let of = |kind, order, rates: bool, extremes| {
            let wanted = CycleMetric {
                slot: 0,
                kind,
                order,
                extremes,
            };
            metric(&column(rates), 1.0, &wanted)
        };
        let refined = Extremes::Refined;
        close(of(CycleKind::Mean, 0, false, refined), 1.5, 1e-12);
        close(of(CycleKind::Harmonic, 1, false, refined), 2.0, 1e-12);
        close(of(CycleKind::Harmonic, 3, false, refined), 0.25, 1e-12);
        close(of(CycleKind::Harmonic, 2, false, refined), 0.0, 1e-12);
        let rms = (1.5f64 * 1.5 + 2.0 * 2.0 / 2.0 + 0.25 * 0.25 / 2.0).sqrt();
        close(of(CycleKind::Rms, 0, false, refined), rms, 1e-12);
        for rates in [false, true] {
            close(of(CycleKind::Max, 0, rates, refined), max, 1e-8);
            close(of(CycleKind::Min, 0, rates, refined), min, 1e-8);
            close(
                of(CycleKind::PeakToPeak, 0, rates, refined),
                max - min,
                2e-8,
            );
            close(
                of(CycleKind::PeakAbs, 0, rates, refined),
                max.max(-min),
                1e-8,
            );
        }
        // Sampled, the peak is a sample's: below the true one.
        let sampled = of(CycleKind::Max, 0, false, Extremes::Sampled);
        assert!(sampled < max && column(false).iter().any(|s| s.x == sampled));
    }
}
