//! What a command stored of the runs it ran, kept in memory for the folder's summaries: the
//! SHA-256 of each `trajectory.csv` it wrote (the summaries count bit-identical repetitions
//! once by it) and, within a budget, the recording as the file holds it (the figures and the
//! report page draw it). The summaries cover every finished run of the folder; the runs of
//! earlier commands, and any beyond the budget, are read back from their files as before, so
//! the folder's files do not depend on which runs a command ran (tested).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use cpmx_recording::Recording;

/// Agent-samples kept in memory at most (48 bytes each: about 50 MB); a recording that would
/// pass it is read back from its file instead.
const AGENT_SAMPLE_BUDGET: usize = 1 << 20;

/// The runs a command stored, by run key.
#[derive(Debug, Default)]
pub struct FreshRuns {
    inner: Mutex<Kept>,
}

#[derive(Debug, Default)]
struct Kept {
    runs: HashMap<String, FreshRun>,
    agent_samples: usize,
}

/// One stored run.
#[derive(Debug, Clone)]
struct FreshRun {
    trajectory_sha256: String,
    recording: Option<Arc<Recording>>,
}

impl FreshRuns {
    /// Notes that the run `key` was stored with a `trajectory.csv` of this SHA-256, from
    /// `recording`.
    pub fn insert(&self, key: &str, trajectory_sha256: String, recording: Recording) {
        let Ok(mut kept) = self.inner.lock() else {
            return;
        };
        let agent_samples = recording.samples.len() * recording.ref_paths.len();
        let recording = (kept.agent_samples + agent_samples <= AGENT_SAMPLE_BUDGET)
            .then(|| recording.stored_copy())
            .flatten()
            .map(Arc::new);
        if recording.is_some() {
            kept.agent_samples += agent_samples;
        }
        kept.runs.insert(
            key.to_owned(),
            FreshRun {
                trajectory_sha256,
                recording,
            },
        );
    }

    /// The SHA-256 of the `trajectory.csv` the run `key` was stored with.
    pub fn trajectory_sha256(&self, key: &str) -> Option<String> {
        let kept = self.inner.lock().ok()?;
        kept.runs.get(key).map(|run| run.trajectory_sha256.clone())
    }

    /// The run `key`'s recording as its `trajectory.csv` holds it, if kept.
    pub fn recording(&self, key: &str) -> Option<Arc<Recording>> {
        let kept = self.inner.lock().ok()?;
        kept.runs.get(key).and_then(|run| run.recording.clone())
    }
}
