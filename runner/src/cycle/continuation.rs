//! Where a point's shooting starts when the previous points of the same chain had steady
//! cycles: the last one's cycle, or, where the last points and this one lie evenly spaced
//! on a line of parameter values (a grid's row), the polynomial through their cycles (a
//! line through two, a parabola through three) extended to this point, whose error is
//! of the order of the spacing to the power of the points used.

use super::periodic::Shot;
use crate::cycle_plan::{CyclePlan, Way};

/// The last points' rows and cycles, the latest last.
#[derive(Default)]
pub struct Continuation {
    history: Vec<(Vec<f64>, Shot)>,
}

/// The most cycles an extrapolation goes through.
const KEPT: usize = 3;
/// Rows this close (relative to their size) are evenly spaced.
const EVEN: f64 = 1e-9;

impl Continuation {
    /// A new chain, or a point without a cycle (the next one cannot extend a line through
    /// it): no history.
    pub fn forget(&mut self) {
        self.history.clear();
    }

    pub fn record(&mut self, row: &[f64], shot: Shot) {
        if self.history.len() == KEPT {
            self.history.remove(0);
        }
        self.history.push((row.to_vec(), shot));
    }

    /// The guess for the point at `row`: the polynomial through the latest cycles whose
    /// rows lie with it evenly spaced on a line, else the last cycle.
    pub fn guess(&self, row: &[f64], plan: &CyclePlan) -> Option<Shot> {
        let (last_row, last) = self.history.last()?;
        if row == last_row.as_slice() {
            return Some(last.clone());
        }
        let mut used = 1;
        while used < self.history.len() {
            let tail = &self.history[self.history.len() - used - 1..];
            if !evenly(tail.iter().map(|(r, _)| r.as_slice()).chain([row])) {
                break;
            }
            used += 1;
        }
        let tail: Vec<&Shot> = self.history[self.history.len() - used..]
            .iter()
            .map(|(_, shot)| shot)
            .collect();
        Some(extrapolated(&tail, plan))
    }
}

/// Whether the rows, in order, are evenly spaced on a line.
fn evenly<'a>(rows: impl Iterator<Item = &'a [f64]>) -> bool {
    let rows: Vec<&[f64]> = rows.collect();
    rows.windows(3).all(|w| {
        w[2].iter().zip(w[1]).zip(w[0]).all(|((c, b), a)| {
            let scale = a.abs().max(b.abs()).max(c.abs()).max(f64::MIN_POSITIVE);
            ((c - b) - (b - a)).abs() <= EVEN * scale
        })
    })
}

/// The polynomial through evenly spaced values (oldest first) at the next step: its
/// weights for one, two and three values.
fn weights(count: usize) -> &'static [f64] {
    match count {
        1 => &[1.0],
        2 => &[-1.0, 2.0],
        _ => &[1.0, -3.0, 3.0],
    }
}

/// The cycles `tail` (oldest first) extended one step: in coordinates where the cyclic
/// state's value on the section does not count (the shifted states relative to it, which
/// stays the last cycle's); through start values the unknowns hold no cyclic state, and
/// each is extended as it is. A period that would not be positive is the last one's.
fn extrapolated(tail: &[&Shot], plan: &CyclePlan) -> Shot {
    let w = weights(tail.len());
    let last = tail[tail.len() - 1];
    let combined = |value: &dyn Fn(&Shot) -> f64| -> f64 {
        tail.iter().zip(w).map(|(shot, w)| w * value(shot)).sum()
    };
    let mut search = last.search.clone();
    let period = combined(&|s| s.search.period);
    if period > 0.0 {
        search.period = period;
    }
    let through = matches!(plan.way, Way::Starts(_));
    let k = plan.state;
    let relative = |i: usize| plan.shifted.contains(&i) && !through;
    let mut x0 = last.x0.clone();
    for (i, x) in x0.iter_mut().enumerate() {
        if i == k && !through {
            continue;
        }
        let line = combined(&|s| s.x0[i] - if relative(i) { s.x0[k] } else { 0.0 });
        *x = line + if relative(i) { last.x0[k] } else { 0.0 };
    }
    Shot {
        x0,
        search,
        ..last.clone()
    }
}
