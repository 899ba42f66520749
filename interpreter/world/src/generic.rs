//! Reference-path numbering for maps other than the CPM Lab map (SigmaRL has none for them):
//! every maximal successor chain and every elementary loop, in a deterministic order, then walks
//! that put every remaining lanelet on a path.
//!
//! Numbering (0-based ids, in this order):
//! 1. **Open chains.** From each lanelet without predecessors (ascending id), a depth-first
//!    walk over successors (ascending id) emits every chain that ends at a lanelet without
//!    successors. A chain that can only continue into its own lanelets (it ran into a cycle)
//!    ends there and is emitted too.
//! 2. **Loops.** For each lanelet `s` (ascending id), every elementary cycle whose lowest
//!    lanelet id is `s`, starting at `s`, found depth-first over successors (ascending id)
//!    through lanelets with ids above `s`.
//! 3. **Coverage.** For each lanelet on no path so far (ascending id), a walk from it that
//!    always takes the lowest-id successor not yet on the walk, until there is none. These
//!    reach lanelets that hang off a loop, and every lanelet of a map whose enumeration stopped
//!    early.
//!
//! The enumerations (1 and 2) stop after [`MAX_GENERIC_PATHS`] paths or [`MAX_SEARCH_STEPS`]
//! search steps in total, so pathological maps cannot hang the loader; coverage walks are
//! linear in the map's size and always run. Steps 1 and 2 number alike whatever step 3 adds,
//! so a map's enumerated ids keep their meaning.

use std::collections::{HashMap, HashSet};

use crate::lanelet::{Lanelet, LaneletId};

/// At most this many paths are enumerated (steps 1 and 2).
pub const MAX_GENERIC_PATHS: usize = 1024;
/// At most this many depth-first steps are spent enumerating.
pub const MAX_SEARCH_STEPS: usize = 1_000_000;

/// A map's generic reference paths as lanelet sequences, numbered by position.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GenericNumbering {
    /// The lanelets of path `i`, in driving order.
    pub sequences: Vec<Vec<LaneletId>>,
    /// How many of them the enumeration found (steps 1 and 2); the rest are coverage walks.
    pub enumerated: usize,
    /// The enumeration stopped at [`MAX_GENERIC_PATHS`] or [`MAX_SEARCH_STEPS`]: some chains
    /// or loops of the map have no number of their own.
    pub stopped_early: bool,
}

/// Numbers a map's generic reference paths (see the module's doc).
pub fn generic_path_lanelets(lanelets: &[Lanelet]) -> GenericNumbering {
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
        stopped_early: false,
    };

    // Open chains from lanelets without predecessors.
    let has_predecessor: HashSet<LaneletId> = lanelets
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
    let enumerated = search.out.len();
    let stopped_early = search.stopped_early;
    let mut sequences = search.out;

    // Coverage walks from the lanelets on no path yet.
    let mut covered: HashSet<LaneletId> = sequences.iter().flatten().copied().collect();
    for &start in &ids {
        if covered.contains(&start) {
            continue;
        }
        let mut walk = vec![start];
        let mut on_walk = HashSet::from([start]);
        while let Some(&next) = walk
            .last()
            .and_then(|last| successors.get(last))
            .and_then(|s| s.iter().find(|n| !on_walk.contains(*n)))
        {
            walk.push(next);
            on_walk.insert(next);
        }
        covered.extend(on_walk);
        sequences.push(walk);
    }
    GenericNumbering {
        sequences,
        enumerated,
        stopped_early,
    }
}

struct Search<'a> {
    successors: &'a HashMap<LaneletId, Vec<LaneletId>>,
    out: Vec<Vec<LaneletId>>,
    steps: usize,
    stopped_early: bool,
}

impl Search<'_> {
    fn exhausted(&mut self) -> bool {
        self.steps += 1;
        if self.out.len() >= MAX_GENERIC_PATHS || self.steps > MAX_SEARCH_STEPS {
            self.stopped_early = true;
        }
        self.stopped_early
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
                } else {
                    self.stopped_early = true;
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
            generic_path_lanelets(&ls).sequences,
            vec![vec![1, 2, 3], vec![1, 2, 4], vec![5, 6]]
        );
        assert!(!generic_path_lanelets(&ls).stopped_early);
    }

    #[test]
    fn numbering_stops_at_its_limit_and_says_so() {
        // Eleven diamonds in a row: 2^11 = 2048 chains from lanelet 0 to the last one.
        let diamonds = 11;
        let mut ls = Vec::new();
        for d in 0..diamonds {
            let (a, b, c, next) = (3 * d, 3 * d + 1, 3 * d + 2, 3 * d + 3);
            ls.push(lanelet(a, &[b, c]));
            ls.push(lanelet(b, &[next]));
            ls.push(lanelet(c, &[next]));
        }
        ls.push(lanelet(3 * diamonds, &[]));
        let numbering = generic_path_lanelets(&ls);
        assert!(numbering.stopped_early);
        assert_eq!(numbering.enumerated, MAX_GENERIC_PATHS);
        // The enumerated chains all start 0 -> 1 (branch 1 first): the coverage walks put the
        // first diamond's other branch, lanelet 2, on a path.
        assert_eq!(
            numbering.sequences[MAX_GENERIC_PATHS..],
            [vec![
                2, 3, 4, 6, 7, 9, 10, 12, 13, 15, 16, 18, 19, 21, 22, 24, 25, 27, 28, 30, 31, 33
            ]]
        );
    }

    #[test]
    fn a_lanelet_hanging_off_a_loop_gets_a_coverage_walk() {
        // The loop 1 -> 2 -> 1 with an exit 2 -> 3 -> 4: 3 and 4 are on no chain (no lanelet
        // lacks a predecessor) and on no loop.
        let ls = [
            lanelet(1, &[2]),
            lanelet(2, &[1, 3]),
            lanelet(3, &[4]),
            lanelet(4, &[]),
        ];
        let numbering = generic_path_lanelets(&ls);
        assert!(!numbering.stopped_early);
        assert_eq!(numbering.enumerated, 1);
        assert_eq!(numbering.sequences, vec![vec![1, 2], vec![3, 4]]);
    }
}
