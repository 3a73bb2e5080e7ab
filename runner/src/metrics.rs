//! Metrics of one variable over a time window, accumulated at communication points so
//! that a sweep that asks for metrics never ships a time series; and the extremes of a
//! sampled variable found between its samples, which a steady cycle's metrics share.
//!
//! A sampled extreme misses the true one by up to the variable's curvature times the
//! squared distance to the nearest sample. Refined, it is the extreme of the cubic through
//! the values and rates at the two samples around it, where the rates are known (an FMU's
//! output derivatives), else of the parabola through the three samples around it.

use serde::Deserialize;

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// The value at the last communication point in the window.
    Final,
    Min,
    Max,
    /// max |x|.
    PeakAbs,
    /// Time average by the trapezoidal rule over the points in the window.
    Mean,
    /// sqrt of the trapezoidal time average of x².
    Rms,
    /// max − min.
    PeakToPeak,
}

impl Kind {
    /// Whether the metric is made of the window's extremes.
    pub fn is_extreme(self) -> bool {
        matches!(
            self,
            Kind::Min | Kind::Max | Kind::PeakAbs | Kind::PeakToPeak
        )
    }
}

/// How a metric's extremes are found: between the samples (the default), or at them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Extremes {
    #[default]
    Refined,
    Sampled,
}

impl Extremes {
    pub fn named(name: &str) -> Result<Extremes, String> {
        match name {
            "refined" => Ok(Extremes::Refined),
            "sampled" => Ok(Extremes::Sampled),
            other => Err(format!(
                "must be \"refined\" (between the samples, the default) or \"sampled\", got \
                 {other:?}"
            )),
        }
    }
}

/// A variable at one time: its value and, where known, its rate of change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub t: f64,
    pub x: f64,
    pub rate: Option<f64>,
}

/// The largest of sign·x (sign ±1) near the sampled extreme `at`, from the samples either
/// side of it (`None` at an end of the samples). Where `at`'s rate is known it says on
/// which side the extreme lies: there, the cubic through the values and rates at both
/// ends where the neighbour's rate is known too, else the parabola through the three
/// samples; no neighbour there, the extreme is `at` itself (an end of the window). Without
/// `at`'s rate, the parabola. Never below the sampled value.
pub fn refined(sign: f64, left: Option<Sample>, at: Sample, right: Option<Sample>) -> f64 {
    let parabola = || match (left, right) {
        (Some(a), Some(c)) => parabola_top(sign, a, at, c),
        _ => sign * at.x,
    };
    let best = match at.rate.map(|d| sign * d) {
        None => parabola(),
        Some(rising) => {
            let toward = if rising > 0.0 { right } else { left };
            match toward {
                _ if rising == 0.0 => sign * at.x,
                None => sign * at.x,
                Some(side) if side.rate.is_some() => {
                    let (a, b) = if side.t < at.t {
                        (side, at)
                    } else {
                        (at, side)
                    };
                    cubic_top(sign, a, b)
                }
                Some(_) => parabola(),
            }
        }
    };
    sign * best.max(sign * at.x)
}

/// The largest of sign·p over [a.t, b.t], p the cubic through the values and rates at both
/// ends.
fn cubic_top(sign: f64, a: Sample, b: Sample) -> f64 {
    let h = b.t - a.t;
    let (y0, y1) = (sign * a.x, sign * b.x);
    let (d0, d1) = (sign * a.rate.unwrap_or(0.0), sign * b.rate.unwrap_or(0.0));
    let value = |w: f64| {
        let (w2, w3) = (w * w, w * w * w);
        (2.0 * w3 - 3.0 * w2 + 1.0) * y0
            + (w3 - 2.0 * w2 + w) * h * d0
            + (-2.0 * w3 + 3.0 * w2) * y1
            + (w3 - w2) * h * d1
    };
    // p′(w) = A w² + B w + C over the step's fraction w.
    let a2 = 6.0 * (y0 - y1) + 3.0 * h * (d0 + d1);
    let b1 = -6.0 * (y0 - y1) - h * (4.0 * d0 + 2.0 * d1);
    let c0 = h * d0;
    let mut best = y0.max(y1);
    for w in quadratic_roots(a2, b1, c0) {
        if w > 0.0 && w < 1.0 {
            best = best.max(value(w));
        }
    }
    best
}

/// The real roots of A w² + B w + C (of B w + C where A vanishes beside B and C).
fn quadratic_roots(a: f64, b: f64, c: f64) -> Vec<f64> {
    if a.abs() <= 1e-12 * (b.abs() + c.abs()) {
        return if b != 0.0 { vec![-c / b] } else { Vec::new() };
    }
    let discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        return Vec::new();
    }
    // The root of larger size first, the other from the product: no cancellation.
    let q = -0.5 * (b + b.signum() * discriminant.sqrt());
    if q == 0.0 {
        return vec![0.0];
    }
    vec![q / a, c / q]
}

/// The largest of sign·p, p the parabola through three samples, where it bends down
/// (sign·p concave); else the middle sample's.
fn parabola_top(sign: f64, a: Sample, b: Sample, c: Sample) -> f64 {
    let (h0, h1) = (b.t - a.t, c.t - b.t);
    let (y0, y1, y2) = (sign * a.x, sign * b.x, sign * c.x);
    let s0 = (y1 - y0) / h0;
    let s1 = (y2 - y1) / h1;
    let curvature = (s1 - s0) / (h0 + h1);
    if curvature.is_nan() || curvature >= 0.0 {
        return y1;
    }
    // p(t) = y1 + slope (t − b.t) + curvature (t − b.t)², slope the parabola's at b.t.
    let slope = s0 + curvature * h0;
    y1 - slope * slope / (4.0 * curvature)
}

/// The extreme of sign·x over a window's samples so far, with its neighbours.
#[derive(Clone, Debug)]
struct Extreme {
    sign: f64,
    left: Option<Sample>,
    at: Option<Sample>,
    right: Option<Sample>,
    /// Whether the extreme is the last sample pushed (its right neighbour comes next).
    latest: bool,
}

impl Extreme {
    fn new(sign: f64) -> Self {
        Extreme {
            sign,
            left: None,
            at: None,
            right: None,
            latest: false,
        }
    }

    /// Whether a sample of value `x` (after one of `previous`) may end up beside the
    /// extreme or be it, so that its rate is worth reading: the first; one beyond the
    /// extreme that rose from the sample before by less than half the largest change
    /// between samples yet (`largest`; rising as steeply as ever, it is no peak yet); one
    /// short of it, right after it or by less than twice that change.
    fn near(&self, x: f64, previous: Option<f64>, largest: f64) -> bool {
        let Some(at) = self.at else {
            return true;
        };
        let rise = self.sign * (x - at.x);
        match previous {
            Some(p) if rise > 0.0 => self.sign * (x - p) < 0.5 * largest,
            _ => self.latest || rise >= -2.0 * largest,
        }
    }

    fn push(&mut self, previous: Option<Sample>, sample: Sample) {
        let beyond = self
            .at
            .is_none_or(|at| self.sign * sample.x > self.sign * at.x);
        if beyond {
            (self.left, self.at, self.right) = (previous, Some(sample), None);
        } else if self.latest {
            self.right = Some(sample);
        }
        self.latest = beyond;
    }

    fn value(&self, extremes: Extremes) -> Option<f64> {
        let at = self.at?;
        Some(match extremes {
            Extremes::Sampled => at.x,
            Extremes::Refined => refined(self.sign, self.left, at, self.right),
        })
    }
}

/// Points within this fraction of a communication step of a window's end belong to it,
/// so that `from = 2` includes the point computed as 200 × 0.01.
pub const WINDOW_SLACK: f64 = 1e-9;

#[derive(Clone, Debug)]
pub struct Accumulator {
    kind: Kind,
    extremes: Extremes,
    from: f64,
    to: f64,
    count: u64,
    top: Extreme,
    bottom: Extreme,
    previous: Option<Sample>,
    /// The largest change of the variable between two samples yet.
    largest_change: f64,
    first_t: f64,
    integral: f64,
}

impl Accumulator {
    /// `slack` is the absolute time by which a point may lie outside [from, to].
    pub fn new(kind: Kind, extremes: Extremes, from: f64, to: f64, slack: f64) -> Self {
        Self {
            kind,
            extremes,
            from: from - slack,
            to: to + slack,
            count: 0,
            top: Extreme::new(1.0),
            bottom: Extreme::new(-1.0),
            previous: None,
            largest_change: 0.0,
            first_t: f64::NAN,
            integral: 0.0,
        }
    }

    pub fn clear(&mut self) {
        *self = Self {
            from: self.from,
            to: self.to,
            ..Self::new(self.kind, self.extremes, 0.0, 0.0, 0.0)
        };
    }

    /// Whether a point at `t` falls in the window (where its rate, if wanted, is read).
    #[inline]
    pub fn within(&self, t: f64) -> bool {
        t >= self.from && t <= self.to
    }

    /// Whether the metric refines its extremes (and so may want the variable's rate).
    pub fn refines(&self) -> bool {
        self.kind.is_extreme() && self.extremes == Extremes::Refined
    }

    /// Whether the rate at a sample (t, x) may serve the refined extremes: where the
    /// sample may be an extreme or beside one. Reading it only there keeps the rates'
    /// cost to the samples near the peaks; an extreme whose neighbour's rate went unread
    /// is refined by the parabola instead.
    #[inline]
    pub fn wants_rate(&self, t: f64, x: f64) -> bool {
        let (previous, largest) = (self.previous.map(|s| s.x), self.largest_change);
        self.refines()
            && self.within(t)
            && (self.top.near(x, previous, largest) || self.bottom.near(x, previous, largest))
    }

    #[inline]
    pub fn push(&mut self, t: f64, x: f64, rate: Option<f64>) {
        if !self.within(t) {
            return;
        }
        let sample = Sample { t, x, rate };
        let y = match self.kind {
            Kind::Rms => x * x,
            _ => x,
        };
        match self.previous {
            None => self.first_t = t,
            Some(before) => {
                let before_y = if self.kind == Kind::Rms {
                    before.x * before.x
                } else {
                    before.x
                };
                self.integral += 0.5 * (t - before.t) * (y + before_y);
                self.largest_change = self.largest_change.max((x - before.x).abs());
            }
        }
        self.count += 1;
        if self.kind.is_extreme() {
            self.top.push(self.previous, sample);
            self.bottom.push(self.previous, sample);
        }
        self.previous = Some(sample);
    }

    /// None when no communication point fell in the window.
    pub fn value(&self) -> Option<f64> {
        let last = self.previous?;
        let last_y = if self.kind == Kind::Rms {
            last.x * last.x
        } else {
            last.x
        };
        let span = last.t - self.first_t;
        let average = if self.count == 1 || span <= 0.0 {
            last_y
        } else {
            self.integral / span
        };
        let (max, min) = (
            || self.top.value(self.extremes).unwrap_or(last.x),
            || self.bottom.value(self.extremes).unwrap_or(last.x),
        );
        Some(match self.kind {
            Kind::Final => last.x,
            Kind::Min => min(),
            Kind::Max => max(),
            Kind::PeakAbs => max().abs().max(min().abs()),
            Kind::PeakToPeak => max() - min(),
            Kind::Mean => average,
            Kind::Rms => average.sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn over(kind: Kind, from: f64, to: f64, samples: &[(f64, f64)]) -> Option<f64> {
        let mut a = Accumulator::new(kind, Extremes::Sampled, from, to, 1e-12);
        for &(t, x) in samples {
            a.push(t, x, None);
        }
        a.value()
    }

    const SAMPLES: [(f64, f64); 5] = [(0.0, 1.0), (1.0, -3.0), (2.0, 2.0), (3.0, 0.5), (4.0, 4.0)];

    #[test]
    fn each_kind_over_a_window() {
        let at = |kind| over(kind, 1.0, 3.0, &SAMPLES).unwrap();
        assert_eq!(at(Kind::Final), 0.5);
        assert_eq!(at(Kind::Min), -3.0);
        assert_eq!(at(Kind::Max), 2.0);
        assert_eq!(at(Kind::PeakAbs), 3.0);
        assert_eq!(at(Kind::PeakToPeak), 5.0);
        // Trapezoid over t = 1..3: (−3 + 2)/2 + (2 + 0.5)/2 = 0.75, over 2 s.
        assert_eq!(at(Kind::Mean), 0.375);
        // x²: 9, 4, 0.25 → (13/2 + 4.25/2) / 2.
        assert_eq!(at(Kind::Rms), (8.625f64 / 2.0).sqrt());
    }

    #[test]
    fn empty_window_and_single_point() {
        assert_eq!(over(Kind::Max, 5.0, 6.0, &SAMPLES), None);
        assert_eq!(over(Kind::Mean, 2.0, 2.0, &SAMPLES), Some(2.0));
        assert_eq!(over(Kind::Rms, 1.0, 1.0, &SAMPLES), Some(3.0));
    }

    #[test]
    fn clear_forgets_samples_but_keeps_the_window() {
        let mut a = Accumulator::new(Kind::Max, Extremes::Refined, 1.0, 3.0, 0.0);
        a.push(2.0, 7.0, None);
        a.clear();
        assert_eq!(a.value(), None);
        a.push(0.0, 9.0, None);
        a.push(3.0, 1.0, None);
        assert_eq!(a.value(), Some(1.0));
    }

    /// A signal's extremes over a window sampled every `h`, with its rates or without.
    fn extremes_of(h: f64, rates: bool, kind: Kind) -> f64 {
        let signal = |t: f64| (2.0 * t + 0.3).sin() + 0.2 * (5.0 * t).cos();
        let rate = |t: f64| 2.0 * (2.0 * t + 0.3).cos() - (5.0 * t).sin();
        let mut a = Accumulator::new(kind, Extremes::Refined, 0.0, 3.0, 1e-12);
        let steps = (3.0 / h).round() as usize;
        for k in 0..=steps {
            let t = k as f64 * h;
            a.push(t, signal(t), rates.then(|| rate(t)));
        }
        a.value().unwrap()
    }

    #[test]
    fn extremes_are_found_between_the_samples() {
        let signal = |t: f64| (2.0 * t + 0.3).sin() + 0.2 * (5.0 * t).cos();
        let fine: Vec<f64> = (0..=3_000_000).map(|k| signal(k as f64 * 1e-6)).collect();
        let max = fine.iter().copied().fold(f64::MIN, f64::max);
        let min = fine.iter().copied().fold(f64::MAX, f64::min);
        let errors = |h: f64| {
            let mut sampled = Accumulator::new(Kind::Max, Extremes::Sampled, 0.0, 3.0, 1e-12);
            for k in 0..=(3.0 / h).round() as usize {
                sampled.push(k as f64 * h, signal(k as f64 * h), None);
            }
            let swing = extremes_of(h, true, Kind::PeakToPeak);
            assert!(
                (swing - (max - min)).abs() < 1e-5,
                "{h}: {swing} vs {}",
                max - min
            );
            [
                max - sampled.value().unwrap(),
                (extremes_of(h, false, Kind::Max) - max).abs(),
                (extremes_of(h, true, Kind::Max) - max).abs(),
            ]
        };
        let (coarse, fine) = (errors(0.05), errors(0.02));
        // The cubic through values and rates is far closer than the samples.
        assert!(
            coarse[2] < 1e-2 * coarse[0] && fine[2] < 1e-2 * fine[0],
            "{coarse:?} {fine:?}"
        );
        // The samples' error falls as h², the parabola's as h³ (h 2.5 times shorter).
        assert!(coarse[0] / fine[0] < 8.0, "{coarse:?} {fine:?}");
        assert!(coarse[1] / fine[1] > 12.0, "{coarse:?} {fine:?}");
    }

    #[test]
    fn rates_are_wanted_near_the_extremes_alone_and_serve_as_all_would() {
        let signal = |t: f64| (2.0 * t + 0.3).sin() + 0.2 * (5.0 * t).cos();
        let rate = |t: f64| 2.0 * (2.0 * t + 0.3).cos() - (5.0 * t).sin();
        for kind in [Kind::Max, Kind::Min, Kind::PeakToPeak] {
            let mut every = Accumulator::new(kind, Extremes::Refined, 0.0, 30.0, 1e-12);
            let mut asked = every.clone();
            let mut wanted = 0;
            for k in 0..=3000 {
                let t = k as f64 * 0.01;
                every.push(t, signal(t), Some(rate(t)));
                let wants = asked.wants_rate(t, signal(t));
                wanted += usize::from(wants);
                asked.push(t, signal(t), wants.then(|| rate(t)));
            }
            assert_eq!(asked.value(), every.value(), "{kind:?}");
            assert!(wanted < 3001 / 3, "{kind:?}: {wanted}");
        }
        // A variable that only rises, ever faster: its largest value is the window's last,
        // which needs no rate, and few are read.
        let mut ramp = Accumulator::new(Kind::Max, Extremes::Refined, 0.0, 10.0, 1e-12);
        let mut wanted = 0;
        for k in 0..=1000 {
            let t = k as f64 * 0.01;
            let wants = ramp.wants_rate(t, t * t);
            wanted += usize::from(wants);
            ramp.push(t, t * t, wants.then_some(2.0 * t));
        }
        assert_eq!(ramp.value(), Some(100.0));
        assert!(wanted < 10, "{wanted}");
    }

    #[test]
    fn a_refined_extreme_stays_within_the_window() {
        // Rising through the window's end: its largest value is the last sample's.
        let mut a = Accumulator::new(Kind::Max, Extremes::Refined, 0.0, 1.0, 1e-12);
        for k in 0..=10 {
            let t = k as f64 * 0.1;
            a.push(t, t * t, Some(2.0 * t));
        }
        assert_eq!(a.value(), Some(1.0));
    }

    #[test]
    fn the_cubic_and_the_parabola_are_exact_for_their_own_shapes() {
        let s = |t: f64, x: f64, rate: Option<f64>| Sample { t, x, rate };
        // A parabola, uneven spacing: its vertex exactly.
        let p = |t: f64| 3.0 - 2.0 * (t - 0.37) * (t - 0.37);
        let top = refined(
            1.0,
            Some(s(0.1, p(0.1), None)),
            s(0.3, p(0.3), None),
            Some(s(0.8, p(0.8), None)),
        );
        assert!((top - 3.0).abs() < 1e-14, "{top}");
        // A cubic with its rates: its minimum between the samples exactly.
        let c = |t: f64| t * t * t - t;
        let dc = |t: f64| 3.0 * t * t - 1.0;
        let at = |t: f64| s(t, c(t), Some(dc(t)));
        let low = refined(-1.0, Some(at(0.4)), at(0.6), Some(at(0.8)));
        let exact = c(1.0 / 3f64.sqrt());
        assert!((low - exact).abs() < 1e-14, "{low} vs {exact}");
    }
}
