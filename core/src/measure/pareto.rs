//! Pareto fronts over (cost, error) points, with dominance that tolerates measurement noise.

use serde::{Deserialize, Serialize};

/// When one point beats another: both coordinates no worse, and at least one better by more
/// than its margin. Margins keep noise (or float jitter) from declaring a winner; with zero
/// margins this is textbook Pareto dominance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Dominance {
    /// A cost counts as better only when lower by more than this fraction of the other's cost.
    pub cost_rel_margin: f64,
    /// An error counts as better only when lower by more than this (absolute, the error's unit).
    pub error_abs_margin: f64,
}

impl Dominance {
    /// Textbook dominance (no margins).
    pub const STRICT: Self = Self {
        cost_rel_margin: 0.0,
        error_abs_margin: 0.0,
    };

    /// True when `a` dominates `b`; points are `(cost, error)`, lower is better for both.
    /// "No worse" is also judged with the margins, so two points within noise of each other
    /// never dominate one another.
    #[must_use]
    pub fn dominates(&self, a: (f64, f64), b: (f64, f64)) -> bool {
        let cost_slack = self.cost_rel_margin * b.0.abs();
        let cost_no_worse = a.0 <= b.0;
        let error_no_worse = a.1 <= b.1;
        let cost_better = a.0 < b.0 - cost_slack;
        let error_better = a.1 < b.1 - self.error_abs_margin;
        cost_no_worse && error_no_worse && (cost_better || error_better)
    }
}

/// Indices of the points no other point dominates, sorted by cost then error. Points with a
/// non-finite coordinate are never on the front (a failed measurement must not win).
#[must_use]
pub fn pareto_front(points: &[(f64, f64)], dominance: &Dominance) -> Vec<usize> {
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| finite(&points[i]))
        .filter(|&i| {
            !points
                .iter()
                .enumerate()
                .any(|(j, q)| j != i && finite(q) && dominance.dominates(*q, points[i]))
        })
        .collect();
    front.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    front
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_of_hand_made_points() {
        // (cost, error)
        let pts = [
            (1.0, 10.0),          // 0: cheapest: front
            (2.0, 5.0),           // 1: front
            (3.0, 6.0),           // 2: dominated by 1
            (4.0, 1.0),           // 3: front
            (4.0, 2.0),           // 4: dominated by 3 (same cost, worse error)
            (5.0, 1.0),           // 5: dominated by 3 (same error, more cost)
            (f64::NAN, 0.0),      // 6: failed measurement: never on the front
            (0.5, f64::INFINITY), // 7: likewise
        ];
        assert_eq!(pareto_front(&pts, &Dominance::STRICT), vec![0, 1, 3]);
        // Duplicates do not dominate each other: both stay.
        assert_eq!(
            pareto_front(&[(1.0, 1.0), (1.0, 1.0)], &Dominance::STRICT),
            vec![0, 1]
        );
        assert!(pareto_front(&[], &Dominance::STRICT).is_empty());
    }

    #[test]
    fn margins_absorb_noise() {
        let d = Dominance {
            cost_rel_margin: 0.1,
            error_abs_margin: 0.01,
        };
        // 5 % cheaper at equal error: within noise, no dominance.
        assert!(!d.dominates((0.95, 1.0), (1.0, 1.0)));
        // 20 % cheaper: dominates.
        assert!(d.dominates((0.8, 1.0), (1.0, 1.0)));
        // Slightly lower error, equal cost: within margin.
        assert!(!d.dominates((1.0, 0.995), (1.0, 1.0)));
        assert!(d.dominates((1.0, 0.9), (1.0, 1.0)));
        // Better error but any worse cost: never dominates.
        assert!(!d.dominates((1.01, 0.0), (1.0, 1.0)));
        assert!(Dominance::STRICT.dominates((0.99, 1.0), (1.0, 1.0)));
        assert_eq!(
            pareto_front(&[(0.95, 1.0), (1.0, 1.0), (2.0, 2.0)], &d),
            vec![0, 1]
        );
    }
}
