//! Metrics of one variable over a time window, accumulated at communication points so
//! that a sweep that asks for metrics never ships a time series.

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

/// Points within this fraction of a communication step of a window's end belong to it,
/// so that `from = 2` includes the point computed as 200 × 0.01.
pub const WINDOW_SLACK: f64 = 1e-9;

#[derive(Clone, Debug)]
pub struct Accumulator {
    kind: Kind,
    from: f64,
    to: f64,
    count: u64,
    min: f64,
    max: f64,
    last_t: f64,
    last_x: f64,
    first_t: f64,
    integral: f64,
}

impl Accumulator {
    /// `slack` is the absolute time by which a point may lie outside [from, to].
    pub fn new(kind: Kind, from: f64, to: f64, slack: f64) -> Self {
        Self {
            kind,
            from: from - slack,
            to: to + slack,
            count: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            last_t: f64::NAN,
            last_x: f64::NAN,
            first_t: f64::NAN,
            integral: 0.0,
        }
    }

    pub fn clear(&mut self) {
        *self = Self {
            kind: self.kind,
            from: self.from,
            to: self.to,
            ..Self::new(self.kind, 0.0, 0.0, 0.0)
        };
    }

    #[inline]
    pub fn push(&mut self, t: f64, x: f64) {
        if t < self.from || t > self.to {
            return;
        }
        let y = match self.kind {
            Kind::Rms => x * x,
            _ => x,
        };
        if self.count == 0 {
            self.first_t = t;
        } else {
            self.integral += 0.5 * (t - self.last_t) * (y + self.last_x);
        }
        self.count += 1;
        self.min = self.min.min(x);
        self.max = self.max.max(x);
        self.last_t = t;
        self.last_x = y;
    }

    /// None when no communication point fell in the window.
    pub fn value(&self) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let span = self.last_t - self.first_t;
        let average = if self.count == 1 || span <= 0.0 {
            self.last_x
        } else {
            self.integral / span
        };
        Some(match self.kind {
            Kind::Final => self.last_x,
            Kind::Min => self.min,
            Kind::Max => self.max,
            Kind::PeakAbs => self.max.abs().max(self.min.abs()),
            Kind::PeakToPeak => self.max - self.min,
            Kind::Mean => average,
            Kind::Rms => average.sqrt(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn over(kind: Kind, from: f64, to: f64, samples: &[(f64, f64)]) -> Option<f64> {
        let mut a = Accumulator::new(kind, from, to, 1e-12);
        for &(t, x) in samples {
            a.push(t, x);
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
        let mut a = Accumulator::new(Kind::Max, 1.0, 3.0, 0.0);
        a.push(2.0, 7.0);
        a.clear();
        assert_eq!(a.value(), None);
        a.push(0.0, 9.0);
        a.push(3.0, 1.0);
        assert_eq!(a.value(), Some(1.0));
    }
}
