//! Trajectory smoothing (the paper's Eq. 1): each action is replaced by a linearly weighted moving average
//! of the last n raw actions, the most recent weighted most:
//!
//! a_t = sum_{i=1..n} i * raw_{t-n+i} / sum_{i=1..n} i
//!
//! At the start of an episode, when fewer than n actions exist, the average runs over those that do (with
//! their weights), so the first action is taken as it is. n = 1 turns smoothing off.

use crate::contract::character::DOF_COUNT;

#[derive(Debug, Clone)]
pub struct Smoother {
    window: usize,
    /// The last `window` raw actions, oldest first.
    history: Vec<[f32; DOF_COUNT]>,
}

impl Smoother {
    /// A smoother over the last `window` actions (at least 1).
    pub fn new(window: usize) -> Self {
        Self { window: window.max(1), history: Vec::new() }
    }

    /// Forgets the history (at episode reset).
    pub fn reset(&mut self) {
        self.history.clear();
    }

    /// Adds a raw action and returns the smoothed one.
    pub fn push(&mut self, raw: &[f32; DOF_COUNT]) -> [f32; DOF_COUNT] {
        if self.history.len() == self.window {
            self.history.remove(0);
        }
        self.history.push(*raw);
        let mut smoothed = [0.0f32; DOF_COUNT];
        let mut total_weight = 0.0f32;
        for (age_rank, action) in self.history.iter().enumerate() {
            let weight = (age_rank + 1) as f32;
            total_weight += weight;
            for (out, value) in smoothed.iter_mut().zip(action) {
                *out += weight * value;
            }
        }
        smoothed.map(|v| v / total_weight)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(value: f32) -> [f32; DOF_COUNT] {
        [value; DOF_COUNT]
    }

    #[test]
    fn window_one_is_the_identity() {
        let mut smoother = Smoother::new(1);
        for value in [0.3, -1.0, 0.7] {
            assert_eq!(smoother.push(&constant(value)), constant(value));
        }
    }

    #[test]
    fn weights_grow_linearly_with_recency() {
        let mut smoother = Smoother::new(3);
        assert_eq!(smoother.push(&constant(1.0)), constant(1.0));
        // (1*1 + 2*0) / 3
        assert!((smoother.push(&constant(0.0))[0] - 1.0 / 3.0).abs() < 1e-6);
        // (1*1 + 2*0 + 3*-1) / 6
        assert!((smoother.push(&constant(-1.0))[0] - (1.0 - 3.0) / 6.0).abs() < 1e-6);
        // The oldest drops out: (1*0 + 2*-1 + 3*1) / 6
        assert!((smoother.push(&constant(1.0))[0] - 1.0 / 6.0).abs() < 1e-6);
    }

    #[test]
    fn a_constant_sequence_is_unchanged_and_reset_forgets() {
        let mut smoother = Smoother::new(4);
        for _ in 0..6 {
            assert_eq!(smoother.push(&constant(0.5)), constant(0.5));
        }
        smoother.reset();
        assert_eq!(smoother.push(&constant(-0.25)), constant(-0.25));
    }
}
