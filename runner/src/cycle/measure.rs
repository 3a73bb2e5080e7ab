//! Metrics of an output over one cycle, from its values at evenly spaced times of the
//! period: for a smooth periodic output the periodic trapezoidal rule (mean, RMS) and the
//! discrete Fourier sum (a harmonic's amplitude) are exact to rounding once the samples
//! resolve its harmonics, and a peak is found between samples by the parabola through the
//! three nearest.

use crate::cycle_plan::CycleKind;

pub fn metric(values: &[f64], kind: CycleKind, order: u32) -> f64 {
    let m = values.len() as f64;
    match kind {
        CycleKind::Max => peak(values, 1.0),
        CycleKind::Min => -peak(values, -1.0),
        CycleKind::PeakAbs => peak(values, 1.0).max(peak(values, -1.0)),
        CycleKind::PeakToPeak => peak(values, 1.0) + peak(values, -1.0),
        CycleKind::Mean => values.iter().sum::<f64>() / m,
        CycleKind::Rms => (values.iter().map(|v| v * v).sum::<f64>() / m).sqrt(),
        CycleKind::Harmonic => {
            let (mut re, mut im) = (0.0, 0.0);
            for (j, v) in values.iter().enumerate() {
                let angle = std::f64::consts::TAU * (j as u64 * order as u64) as f64 / m;
                re += v * angle.cos();
                im -= v * angle.sin();
            }
            2.0 * re.hypot(im) / m
        }
    }
}

/// The largest value of sign·v over the cycle, refined by a parabola.
fn peak(values: &[f64], sign: f64) -> f64 {
    let m = values.len();
    let (i, _) = values
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (i, &v)| {
            if sign * v > best.1 {
                (i, sign * v)
            } else {
                best
            }
        });
    let (a, b, c) = (
        sign * values[(i + m - 1) % m],
        sign * values[i],
        sign * values[(i + 1) % m],
    );
    let curvature = a - 2.0 * b + c;
    if curvature < 0.0 {
        b - (a - c) * (a - c) / (8.0 * curvature)
    } else {
        b
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
        let values: Vec<f64> = (0..m).map(|j| signal(j as f64 / m as f64)).collect();
        let fine: Vec<f64> = (0..1_000_000).map(|j| signal(j as f64 / 1e6)).collect();
        let (max, min) = fine
            .iter()
            .fold((f64::MIN, f64::MAX), |(a, b), &v| (a.max(v), b.min(v)));
        let close = |a: f64, b: f64, tol: f64| assert!((a - b).abs() <= tol, "{a} vs {b}");
        close(metric(&values, CycleKind::Mean, 0), 1.5, 1e-12);
        close(metric(&values, CycleKind::Harmonic, 1), 2.0, 1e-12);
        close(metric(&values, CycleKind::Harmonic, 3), 0.25, 1e-12);
        close(metric(&values, CycleKind::Harmonic, 2), 0.0, 1e-12);
        let rms = (1.5f64 * 1.5 + 2.0 * 2.0 / 2.0 + 0.25 * 0.25 / 2.0).sqrt();
        close(metric(&values, CycleKind::Rms, 0), rms, 1e-12);
        close(metric(&values, CycleKind::Max, 0), max, 1e-8);
        close(metric(&values, CycleKind::Min, 0), min, 1e-8);
        close(metric(&values, CycleKind::PeakToPeak, 0), max - min, 2e-8);
        close(metric(&values, CycleKind::PeakAbs, 0), max.max(-min), 1e-8);
    }
}
