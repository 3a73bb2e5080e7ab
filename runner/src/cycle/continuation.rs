//! Where a point's shooting starts when the previous points of the same request had steady
//! cycles: the last one's cycle, or, where the last two points and this one lie evenly
//! spaced on a line of parameter values (a grid's row), the straight line through their
//! cycles extended to this point, whose error is second order in the spacing instead of
//! first.

use super::periodic::Shot;
use crate::cycle_plan::{CyclePlan, Way};

/// The last two points' rows and cycles, the latest last.
#[derive(Default)]
pub struct Continuation {
    history: Vec<(Vec<f64>, Shot)>,
}

/// Rows this close (relative to their size) are evenly spaced.
const EVEN: f64 = 1e-9;

impl Continuation {
    /// A new plan, or a point without a cycle (the next one cannot extend a line through
    /// it): no history.
    pub fn forget(&mut self) {
        self.history.clear();
    }

    pub fn record(&mut self, row: &[f64], shot: Shot) {
        if self.history.len() == 2 {
            self.history.remove(0);
        }
        self.history.push((row.to_vec(), shot));
    }

    /// The guess for the point at `row`: the line through the last two cycles where the
    /// three rows are evenly spaced on a line, else the last cycle.
    pub fn guess(&self, row: &[f64], plan: &CyclePlan) -> Option<Shot> {
        let (last_row, last) = self.history.last()?;
        let [(first_row, first), _] = self.history.as_slice() else {
            return Some(last.clone());
        };
        let evenly = row.iter().zip(last_row).zip(first_row).all(|((c, b), a)| {
            let scale = a.abs().max(b.abs()).max(c.abs()).max(f64::MIN_POSITIVE);
            ((c - b) - (b - a)).abs() <= EVEN * scale
        });
        if !evenly || row == last_row.as_slice() {
            return Some(last.clone());
        }
        Some(extended(first, last, plan))
    }
}

/// 2·last − first, in coordinates where the cyclic state's value on the section does not
/// count: the shifted states relative to it, which stays the last cycle's. Through start
/// values the unknowns hold no cyclic state, and each is extended as it is.
fn extended(first: &Shot, last: &Shot, plan: &CyclePlan) -> Shot {
    let (a, b) = (first.search.period, last.search.period);
    let mut search = last.search.clone();
    search.period = if 2.0 * b - a > 0.0 { 2.0 * b - a } else { b };
    if matches!(plan.way, Way::Starts(_)) {
        let x0 = last
            .x0
            .iter()
            .zip(&first.x0)
            .map(|(b, a)| 2.0 * b - a)
            .collect();
        return Shot {
            x0,
            search,
            ..last.clone()
        };
    }
    let k = plan.state;
    let relative = |x: &[f64], i: usize| {
        if plan.shifted.contains(&i) {
            x[i] - x[k]
        } else {
            x[i]
        }
    };
    let mut x0 = last.x0.clone();
    for i in (0..x0.len()).filter(|&i| i != k) {
        let line = 2.0 * relative(&last.x0, i) - relative(&first.x0, i);
        x0[i] = if plan.shifted.contains(&i) {
            line + last.x0[k]
        } else {
            line
        };
    }
    Shot {
        x0,
        search,
        ..last.clone()
    }
}
