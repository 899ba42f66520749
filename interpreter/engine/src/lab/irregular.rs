//! What a lab run noticed without ending: late, repeated and out-of-order ticks, vehicles
//! missing from the lists or with old positioning fixes, a restarted middleware, silences, the
//! lab's clock far from this machine's, and the planner's latency per tick with the ticks
//! whose trajectories left a vehicle less than its lead time. Kept with the run as notes
//! (`metrics.json`, or `failed.json` for a run that failed).

/// A tick counts as late when it follows the previous one by more than this many periods.
pub const LATE_TICK_PERIODS: f64 = 1.5;

/// A silence (wall clock between two lists) longer than this is noted [s].
pub const NOTED_SILENCE_S: f64 = 1.0;

/// A difference between the lab's clock and this machine's beyond this is noted [s].
pub const NOTED_CLOCK_OFFSET_S: f64 = 0.5;

/// What a run noticed.
#[derive(Debug, Clone, PartialEq, Default)]
pub(super) struct Irregularities {
    /// Ticks that followed the previous one by more than [`LATE_TICK_PERIODS`] periods.
    pub late_ticks: usize,
    /// The longest time between two ticks on the lab's clock [s].
    pub longest_gap_s: f64,
    /// Lists of a tick already answered (answered again).
    pub repeated_ticks: usize,
    /// Lists older than the newest one (ignored).
    pub old_lists: usize,
    /// Per agent: ticks whose list had no new state of its vehicle.
    pub missing: Vec<usize>,
    /// Per agent: ticks whose state carried a positioning fix older than the preflight's
    /// freshness, and the oldest one [s].
    pub old_fixes: Vec<(usize, f64)>,
    /// Ticks after which the middleware restarted (a new start trigger).
    pub restarts: Vec<usize>,
    /// The longest silence between two lists on this machine's clock [s].
    pub longest_silence_s: f64,
    /// The lab's clock minus this machine's at the first tick [s].
    pub clock_offset_s: Option<f64>,
    /// How the lab ended the run before `timing.steps` ticks, if it did.
    pub stopped: Option<String>,
    /// Where misplaced vehicles started (`misplaced: record`).
    pub recorded_starts: Option<String>,
    /// The planner's latency per tick: from the list's arrival to its commands sent [s].
    pub latency_s: Vec<f64>,
    /// Ticks at which a vehicle was left less than its lead time.
    pub lead_misses: usize,
}

impl Irregularities {
    pub fn new(agents: usize) -> Self {
        Self {
            missing: vec![0; agents],
            old_fixes: vec![(0, 0.0); agents],
            ..Self::default()
        }
    }

    /// The notes of the run: what happened (one line, if anything did), where misplaced
    /// vehicles started, and the planner's latency.
    pub fn notes(&self, vehicle_ids: &[u8]) -> Vec<String> {
        let mut parts = Vec::new();
        if let Some(reason) = &self.stopped {
            parts.push(reason.clone());
        }
        if self.late_ticks > 0 {
            parts.push(format!(
                "{} late ticks (planned anyway; longest gap {:.2} s)",
                self.late_ticks, self.longest_gap_s
            ));
        }
        if self.repeated_ticks > 0 {
            parts.push(format!("{} repeated ticks (answered again)", self.repeated_ticks));
        }
        if self.old_lists > 0 {
            parts.push(format!("{} lists out of order (ignored)", self.old_lists));
        }
        for (id, count) in vehicle_ids.iter().zip(&self.missing).filter(|(_, c)| **c > 0) {
            parts.push(format!(
                "vehicle {id} missing from {count} ticks (its last state was used)"
            ));
        }
        for (id, (count, oldest_s)) in vehicle_ids.iter().zip(&self.old_fixes).filter(|(_, c)| c.0 > 0) {
            parts.push(format!(
                "vehicle {id}: positioning fixes up to {oldest_s:.2} s old in {count} ticks"
            ));
        }
        for tick in &self.restarts {
            parts.push(format!(
                "the lab's middleware restarted after tick {tick} (a new start trigger; the run went on)"
            ));
        }
        if self.longest_silence_s > NOTED_SILENCE_S {
            parts.push(format!(
                "the lab was silent for up to {:.2} s between ticks",
                self.longest_silence_s
            ));
        }
        if let Some(offset_s) = self.clock_offset_s.filter(|o| o.abs() > NOTED_CLOCK_OFFSET_S) {
            parts.push(format!(
                "the lab's clock is {:.2} s {} this machine's (the driver keeps to the lab's)",
                offset_s.abs(),
                if offset_s > 0.0 { "ahead of" } else { "behind" }
            ));
        }
        let mut notes = Vec::new();
        if !parts.is_empty() {
            notes.push(parts.join("; "));
        }
        notes.extend(self.recorded_starts.clone());
        if let Some(latency) = self.latency_note() {
            notes.push(latency);
        }
        notes
    }

    /// The planner's latency over the run's ticks, and the ticks that missed the lead time.
    fn latency_note(&self) -> Option<String> {
        if self.latency_s.is_empty() {
            return None;
        }
        let mut sorted = self.latency_s.clone();
        sorted.sort_by(f64::total_cmp);
        let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize] * 1e3;
        Some(format!(
            "planning latency: median {:.1} ms, 95th percentile {:.1} ms, max {:.1} ms over {} ticks; \
             {} ticks left a vehicle less than the lab's {} s lead time",
            at(0.5),
            at(0.95),
            at(1.0),
            sorted.len(),
            self.lead_misses,
            super::VEHICLE_LEAD_S
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_summarise_what_happened() {
        let mut notes = Irregularities::new(2);
        assert_eq!(notes.notes(&[3, 5]), Vec::<String>::new());
        notes.late_ticks = 2;
        notes.longest_gap_s = 0.3;
        notes.missing[1] = 4;
        notes.old_fixes[0] = (3, 0.8);
        notes.restarts.push(12);
        notes.clock_offset_s = Some(-2.0);
        notes.latency_s = vec![0.002, 0.001, 0.003];
        notes.lead_misses = 1;
        let lines = notes.notes(&[3, 5]);
        assert_eq!(lines.len(), 2, "{lines:?}");
        let line = &lines[0];
        assert!(line.contains("2 late ticks"), "{line}");
        assert!(line.contains("vehicle 5 missing from 4 ticks"), "{line}");
        assert!(
            line.contains("vehicle 3: positioning fixes up to 0.80 s old in 3 ticks"),
            "{line}"
        );
        assert!(line.contains("restarted after tick 12"), "{line}");
        assert!(line.contains("2.00 s behind"), "{line}");
        assert!(lines[1].contains("median 2.0 ms"), "{}", lines[1]);
        assert!(
            lines[1].contains("max 3.0 ms over 3 ticks; 1 ticks left"),
            "{}",
            lines[1]
        );
    }
}
