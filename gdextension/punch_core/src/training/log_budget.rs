//! A budget for log lines that outsiders can cause (a training server's refusals and closures): the first
//! lines of each interval are logged, the rest only counted and summed up in one line when the interval ends.
//! So no one who can reach the port can make the server's log grow faster than the budget, or fill the pipe
//! its trainer reads it through.

use std::time::{Duration, Instant};

/// How many lines an interval may log, and what was left out of the current one.
#[derive(Debug, Clone)]
pub struct LogBudget {
    lines_per_interval: usize,
    interval: Duration,
    interval_start: Instant,
    logged: usize,
    left_out: usize,
}

impl LogBudget {
    /// A budget of `lines_per_interval` lines per `interval`, the first interval starting `now`.
    pub fn new(lines_per_interval: usize, interval: Duration, now: Instant) -> Self {
        Self { lines_per_interval, interval, interval_start: now, logged: 0, left_out: 0 }
    }

    /// The lines to log for `line` at `now`: the summary of the interval that ended, if it left lines out,
    /// then `line` itself if the budget still has room (else it is counted as left out).
    pub fn admit(&mut self, line: String, now: Instant) -> Vec<String> {
        let mut lines: Vec<String> = self.summary(now).into_iter().collect();
        if self.logged < self.lines_per_interval {
            self.logged += 1;
            lines.push(line);
        } else {
            self.left_out += 1;
        }
        lines
    }

    /// Once the interval that `now` ends has passed: the line that says how many lines it left out (None if
    /// it left none out), and a new interval starts.
    pub fn summary(&mut self, now: Instant) -> Option<String> {
        if now.saturating_duration_since(self.interval_start) < self.interval {
            return None;
        }
        let left_out = std::mem::take(&mut self.left_out);
        let seconds = now.saturating_duration_since(self.interval_start).as_secs_f32();
        self.interval_start = now;
        self.logged = 0;
        (left_out > 0).then(|| {
            format!(
                "{left_out} more such lines in the last {seconds:.0} s were not logged (at most {} per {} s)",
                self.lines_per_interval,
                self.interval.as_secs_f32()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_lines_are_logged_and_the_rest_summed_up_once_the_interval_ends() {
        let start = Instant::now();
        let mut budget = LogBudget::new(3, Duration::from_secs(10), start);
        let logged: Vec<String> = (0..300).flat_map(|i| budget.admit(format!("line {i}"), start)).collect();
        assert_eq!(logged, ["line 0", "line 1", "line 2"]);
        assert_eq!(budget.summary(start + Duration::from_secs(9)), None, "the interval has not ended");
        let later = budget.admit("line 300".into(), start + Duration::from_secs(11));
        assert_eq!(later.len(), 2, "{later:?}");
        assert!(later[0].starts_with("297 more such lines in the last 11 s"), "{later:?}");
        assert_eq!(later[1], "line 300");
    }

    #[test]
    fn an_interval_that_left_nothing_out_says_nothing() {
        let start = Instant::now();
        let mut budget = LogBudget::new(3, Duration::from_secs(10), start);
        assert_eq!(budget.admit("one".into(), start), ["one"]);
        assert_eq!(budget.summary(start + Duration::from_secs(20)), None);
        assert_eq!(budget.admit("two".into(), start + Duration::from_secs(20)), ["two"]);
    }
}
