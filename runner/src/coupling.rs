//! The communication step of a system with a coupling tolerance: chosen step by step from
//! an estimate of the coupling error, inside each step of the output grid.
//!
//! The estimate needs no extra step. Over a communication step each input follows what the
//! target was given at the step's start: the source's value, held, or moved along its
//! Taylor polynomial (value and output derivatives). After the step the source's actual
//! output is known, and the distance between it and that polynomial at the step's end is
//! how far the input the target integrated with had drifted from the truth: the coupling
//! error the step made, of order k + 1 in the step for derivatives up to order k. It is
//! measured in units of each connection's scale, max(1, the largest |value| seen so far),
//! and a step whose largest estimate exceeds the tolerance is rejected: every component is
//! put back into the FMU state saved at the step's start, and the step is taken again,
//! shorter. The next step's size comes from a PI controller on the estimates.

use serde::Serialize;

/// The smallest communication step, as a fraction of the output grid's step: below it a
/// step whose estimate still exceeds the tolerance ends the point. Small, because held
/// inputs (an estimate of order 1) need steps in proportion to the tolerance: a motor
/// whose torque rises at thousands of N·m/s from zero needs steps of 10⁻⁹ s at a
/// tolerance of 10⁻⁵ until the torque has grown; what ends a point is an estimate that
/// does not fall with the step (an output that jumps), and that takes a few more
/// rejections to tell here than with a larger floor.
pub const MIN_STEP_FRACTION: f64 = 1e-9;

/// What a point reports of its coupling.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct CouplingRecord {
    /// The largest estimate of an accepted step, in units of the connections' scales.
    pub worst_estimate: f64,
    pub accepted: u64,
    pub rejected: u64,
    /// The smallest accepted step.
    pub min_step: f64,
}

/// What becomes of a step tried with a given estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Verdict {
    Accept,
    Reject,
    /// The estimate exceeds the tolerance at the smallest step: the point cannot meet it.
    GiveUp,
}

/// The rule of a coupling tolerance: a relative error, finite, in (0, 1).
pub fn check_tolerance(tolerance: f64) -> Result<(), String> {
    if tolerance.is_finite() && 0.0 < tolerance && tolerance < 1.0 {
        Ok(())
    } else {
        Err(format!(
            "system.coupling_tolerance: must be a number in (0, 1), got {tolerance}"
        ))
    }
}

/// A connection as the estimate sees it: whether it carries a Real (only those drift
/// along a polynomial) and how many derivatives it passes with its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Connection {
    pub real: bool,
    pub derivatives: usize,
}

/// The step-size controller of one system instance, with the estimate it judges by.
pub struct Controller {
    tolerance: f64,
    connections: Vec<Connection>,
    /// Per connection, the largest |value| passed so far (at least 1): its drift's unit.
    scales: Vec<f64>,
    /// The order of the estimate in the step: 1 + the fewest derivatives a connection
    /// passes.
    order: f64,
    /// The next step's size; 0 before the first.
    proposed: f64,
    /// The previous accepted step's estimate over the tolerance.
    previous: f64,
    report: CouplingRecord,
}

impl Controller {
    pub fn new(tolerance: f64, connections: Vec<Connection>) -> Self {
        let fewest = connections.iter().map(|c| c.derivatives).min().unwrap_or(0);
        Self {
            tolerance,
            scales: vec![1.0; connections.len()],
            connections,
            order: 1.0 + fewest as f64,
            proposed: 0.0,
            previous: 1.0,
            report: CouplingRecord {
                worst_estimate: 0.0,
                accepted: 0,
                rejected: 0,
                min_step: f64::INFINITY,
            },
        }
    }

    /// Forget the last point: a new point starts from the output grid's step, and its
    /// connections' scales from 1.
    pub fn restart(&mut self) {
        *self = Self::new(self.tolerance, std::mem::take(&mut self.connections));
    }

    /// The estimate of a step of `h`: the largest drift of a Real connection, what its
    /// target is given now (`now`) against the polynomial it was given at the step's
    /// start (`given`), in its scale; and the connection that drifted most.
    pub fn estimate(&self, given: &[[f64; 3]], now: &[[f64; 3]], h: f64) -> (f64, Option<usize>) {
        let mut largest = (0.0_f64, None);
        for (k, c) in self.connections.iter().enumerate() {
            if c.real {
                let d = drift(&given[k], c.derivatives, h, now[k][0]);
                let relative = d / self.scales[k].max(now[k][0].abs());
                if largest.1.is_none() || relative > largest.0 {
                    largest = (relative, Some(k));
                }
            }
        }
        largest
    }

    /// After an accepted step that passed `given`: each connection's scale grows to the
    /// largest |value| passed so far.
    pub fn widen_scales(&mut self, given: &[[f64; 3]]) {
        for (scale, given) in self.scales.iter_mut().zip(given) {
            *scale = scale.max(given[0].abs());
        }
    }

    /// The step of about which a connection passing `derivatives` would meet the
    /// tolerance, from its `estimate` over a step of `h`.
    pub fn step_needed(&self, h: f64, estimate: f64, derivatives: usize) -> f64 {
        h * (self.tolerance / estimate).powf(1.0 / (1.0 + derivatives as f64))
    }

    pub fn report(&self) -> CouplingRecord {
        self.report
    }

    pub fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// The step to try from `t` within the grid step [.., `end`] of size `grid`: the
    /// proposed one, landing exactly on `end` when it would reach it or leave a sliver.
    pub fn next_step(&self, t: f64, end: f64, grid: f64) -> f64 {
        let left = end - t;
        let h = if self.proposed > 0.0 {
            self.proposed
        } else {
            grid
        };
        if h >= left * (1.0 - 1e-9) || left - h < 1e-9 * grid {
            left
        } else if h > 0.5 * left {
            // Two equal steps to the grid point, not a full one and a sliver.
            0.5 * left
        } else {
            h
        }
    }

    /// Judge a step of size `h` whose largest estimate is `estimate` (in scale units), and
    /// propose the next one.
    pub fn judge(&mut self, h: f64, estimate: f64, grid: f64) -> Verdict {
        let ratio = estimate / self.tolerance;
        let q = self.order;
        if ratio <= 1.0 {
            // PI control: the step grows as the estimates fall, damped by the last one.
            let fac = 0.9 * ratio.max(1e-10).powf(-0.7 / q) * self.previous.max(1e-4).powf(0.4 / q);
            let grown = h * fac.clamp(0.2, 5.0);
            // A step shortened to land on the grid says nothing against the step proposed.
            self.proposed = if h < self.proposed {
                grown.max(self.proposed)
            } else {
                grown
            };
            self.previous = ratio;
            let r = &mut self.report;
            r.accepted += 1;
            r.worst_estimate = r.worst_estimate.max(estimate);
            r.min_step = r.min_step.min(h);
            return Verdict::Accept;
        }
        self.report.rejected += 1;
        if h <= MIN_STEP_FRACTION * grid * (1.0 + 1e-9) {
            return Verdict::GiveUp;
        }
        let fac = (0.9 * ratio.powf(-1.0 / q)).clamp(0.1, 0.9);
        self.proposed = (h * fac).max(MIN_STEP_FRACTION * grid);
        Verdict::Reject
    }
}

/// How far a connection's actual output `now`, `h` after the step's start, lies from the
/// polynomial its target was given (value and derivatives at the start).
fn drift(given: &[f64; 3], derivatives: usize, h: f64, now: f64) -> f64 {
    let mut predicted = given[0];
    if derivatives >= 1 {
        predicted += h * given[1];
    }
    if derivatives >= 2 {
        predicted += 0.5 * h * h * given[2];
    }
    (now - predicted).abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_lands_on_the_grid_without_a_sliver() {
        let mut c = Controller::new(
            1e-4,
            vec![Connection {
                real: true,
                derivatives: 2,
            }],
        );
        assert_eq!(c.next_step(0.0, 0.01, 0.01), 0.01);
        c.proposed = 0.004;
        assert_eq!(c.next_step(0.0, 0.01, 0.01), 0.004);
        assert_eq!(c.next_step(0.008, 0.01, 0.01), 0.01 - 0.008);
        c.proposed = 0.01 - 0.008 - 1e-13;
        assert_eq!(c.next_step(0.008, 0.01, 0.01), 0.01 - 0.008);
        // Between one and two proposed steps from the grid point: two equal ones.
        c.proposed = 0.004;
        assert_eq!(c.next_step(0.004, 0.01, 0.01), 0.003);
    }

    #[test]
    fn a_step_shortened_to_land_keeps_the_step_proposed() {
        let mut c = Controller::new(
            1e-4,
            vec![Connection {
                real: true,
                derivatives: 2,
            }],
        );
        c.proposed = 0.004;
        assert_eq!(c.judge(0.001, 1e-9, 0.01), Verdict::Accept);
        assert_eq!(c.proposed, 0.005); // grown fivefold, no less than before
        c.proposed = 0.004;
        assert_eq!(c.judge(0.0001, 1e-9, 0.01), Verdict::Accept);
        assert_eq!(c.proposed, 0.004);
    }

    #[test]
    fn a_large_estimate_shrinks_the_step_and_a_small_one_grows_it() {
        let mut c = Controller::new(
            1e-4,
            vec![Connection {
                real: true,
                derivatives: 2,
            }],
        );
        assert_eq!(c.judge(0.01, 1e-2, 0.01), Verdict::Reject);
        assert!(c.proposed < 0.01 * 0.5);
        let shrunk = c.proposed;
        assert_eq!(c.judge(shrunk, 1e-6, 0.01), Verdict::Accept);
        assert!(c.proposed > shrunk);
        let r = c.report();
        assert_eq!((r.accepted, r.rejected, r.min_step), (1, 1, shrunk));
        assert_eq!(r.worst_estimate, 1e-6);
    }

    #[test]
    fn an_estimate_too_large_at_the_smallest_step_gives_up() {
        let mut c = Controller::new(
            1e-4,
            vec![Connection {
                real: true,
                derivatives: 0,
            }],
        );
        let smallest = MIN_STEP_FRACTION * 0.01;
        assert_eq!(c.judge(smallest, 1.0, 0.01), Verdict::GiveUp);
    }

    #[test]
    fn the_drift_is_the_distance_from_the_polynomial_given() {
        let given = [1.0, 2.0, 4.0];
        assert_eq!(drift(&given, 0, 0.5, 1.0), 0.0);
        assert_eq!(drift(&given, 1, 0.5, 2.0), 0.0);
        assert_eq!(drift(&given, 2, 0.5, 2.5), 0.0);
        assert_eq!(drift(&given, 2, 0.5, 3.0), 0.5);
    }

    /// The rule the spec's check states too (fmusweep's system.py): a number in (0, 1).
    #[test]
    fn a_coupling_tolerance_is_a_number_in_zero_to_one() {
        for bad in [0.0, 1.0, -1e-5, 2.0, f64::NAN, f64::INFINITY] {
            assert!(
                check_tolerance(bad).unwrap_err().contains("(0, 1)"),
                "{bad}"
            );
        }
        for good in [1e-12, 1e-5, 0.5] {
            assert!(check_tolerance(good).is_ok(), "{good}");
        }
    }
}
