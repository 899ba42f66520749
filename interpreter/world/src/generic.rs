//! Reference-path numbering for maps other than the CPM Lab map (SigmaRL has none for them):
//! every maximal successor chain and every elementary loop, in a deterministic order.
//!
//! Numbering (0-based ids, in this order):
//! 1. **Open chains.** From each lanelet without predecessors (ascending id), a depth-first
//!    walk over successors (ascending id) emits every chain that ends at a lanelet without
//!    successors. A chain that would revisit one of its own lanelets (it ran into a cycle) ends
//!    before the repeat and is emitted too.
//! 2. **Loops.** For each lanelet `s` (ascending id), every elementary cycle whose lowest
//!    lanelet id is `s`, starting at `s`, found depth-first over successors (ascending id)
//!    through lanelets with ids above `s`.
//!
//! Both enumerations stop after [`MAX_GENERIC_PATHS`] paths or [`MAX_SEARCH_STEPS`] search
//! steps in total, so pathological maps cannot hang the loader.

use std::collections::HashMap;

use crate::lanelet::{Lanelet, LaneletId};

/// At most this many generic paths are numbered.
pub const MAX_GENERIC_PATHS: usize = 1024;
/// At most this many depth-first steps are spent enumerating.
pub const MAX_SEARCH_STEPS: usize = 1_000_000;

/// The lanelet sequences of a map's generic reference paths, numbered by position.
pub fn generic_path_lanelets(lanelets: &[Lanelet]) -> Vec<Vec<LaneletId>> {
    let successors: HashMap<LaneletId, Vec<LaneletId>> = lanelets
        .iter()
        .map(|l| {
            let mut s: Vec<LaneletId> = l.successors.clone();
            s.sort_unstable();
            s.dedup();
            (l.id, s)
        })
        .collect();
    let mut ids: Vec<LaneletId> = lanelets.iter().map(|l| l.id).collect();
    ids.sort_unstable();
    let mut search = Search {
        successors: &successors,
        out: Vec::new(),
        steps: 0,
    };

    // Open chains from lanelets without predecessors.
    let has_predecessor: std::collections::HashSet<LaneletId> = lanelets
        .iter()
        .flat_map(|l| l.successors.iter().copied())
        .collect();
    for &start in ids.iter().filter(|id| !has_predecessor.contains(id)) {
        search.chains(&mut vec![start]);
    }

    // Elementary loops, each from its lowest lanelet id.
    for &start in &ids {
        search.cycles(start, &mut vec![start]);
    }
    search.out
}

struct Search<'a> {
    successors: &'a HashMap<LaneletId, Vec<LaneletId>>,
    out: Vec<Vec<LaneletId>>,
    steps: usize,
}

impl Search<'_> {
    fn exhausted(&mut self) -> bool {
        self.steps += 1;
        self.out.len() >= MAX_GENERIC_PATHS || self.steps > MAX_SEARCH_STEPS
    }

    fn chains(&mut self, chain: &mut Vec<LaneletId>) {
        if self.exhausted() {
            return;
        }
        let Some(&last) = chain.last() else { return };
        let next = self.successors.get(&last).map_or(&[][..], Vec::as_slice);
        if next.is_empty() || next.iter().all(|n| chain.contains(n)) {
            self.out.push(chain.clone());
            return;
        }
        for &n in next {
            if chain.contains(&n) {
                continue;
            }
            chain.push(n);
            self.chains(chain);
            chain.pop();
        }
    }

    fn cycles(&mut self, start: LaneletId, chain: &mut Vec<LaneletId>) {
        if self.exhausted() {
            return;
        }
        let Some(&last) = chain.last() else { return };
        let next = self.successors.get(&last).map_or(&[][..], Vec::as_slice);
        for &n in next {
            if n == start {
                if self.out.len() < MAX_GENERIC_PATHS {
                    self.out.push(chain.clone());
                }
            } else if n > start && !chain.contains(&n) {
                chain.push(n);
                self.cycles(start, chain);
                chain.pop();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polyline::Polyline;

    fn lanelet(id: LaneletId, successors: &[LaneletId]) -> Lanelet {
        Lanelet {
            id,
            left_boundary: Polyline::default(),
            right_boundary: Polyline::default(),
            center_line: Polyline::default(),
            left_line_marking: None,
            right_line_marking: None,
            predecessors: Vec::new(),
            successors: successors.to_vec(),
            adjacent_left: None,
            adjacent_right: None,
            lanelet_types: Vec::new(),
            location: Default::default(),
        }
    }

    #[test]
    fn chains_then_loops_in_id_order() {
        // 1 -> 2 -> {3, 4}; 5 -> 6 -> 5 (a loop); 7 -> 8 -> 7 found from 7.
        let ls = [
            lanelet(1, &[2]),
            lanelet(2, &[4, 3]),
            lanelet(3, &[]),
            lanelet(4, &[]),
            lanelet(6, &[5]),
            lanelet(5, &[6]),
        ];
        assert_eq!(
            generic_path_lanelets(&ls),
            vec![vec![1, 2, 3], vec![1, 2, 4], vec![5, 6]]
        );
    }
}
