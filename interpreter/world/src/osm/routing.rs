//! Successors and neighbours as Lanelet2's routing graph has them for a vehicle
//! (`lanelet2_routing`'s `RoutingGraphBuilder` under the rules of `rules.rs`), on the lanelets
//! a vehicle may pass, each two-way lanelet also inverted:
//! - **Following.** B follows A when A's left and right bounds end at the nodes where B's left
//!   and right bounds start (`geometry::follows`), in the orientation both are driven.
//! - **Neighbours.** B is A's left neighbour when B's right bound is A's left bound, the same way
//!   in the same orientation (`geometry::leftOf`), and B does not follow A; right neighbours
//!   alike. A lane change to it (`left`/`right` in the graph rather than `adjacentLeft`/
//!   `adjacentRight`) is allowed when the shared bound allows a change that way (`rules.rs`),
//!   read along the bound as A drives it.
//! - **Oncoming lanes.** Lanelet2's graph has no relation for them; cpmx adds, for a lanelet with
//!   no same-direction neighbour on its left, the lanelet whose left bound is its left bound run
//!   backwards (no lane change to it).

use std::collections::HashMap;

use super::rules::LaneChange;
use crate::lanelet::{Adjacent, DrivingDirection, LaneletId};

/// A bound as a lanelet drives it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bound {
    /// The way's id.
    pub way: i64,
    /// Whether it is driven against the way's stored node order.
    pub inverted: bool,
    /// Its nodes in driving order.
    pub nodes: Vec<i64>,
}

impl Bound {
    /// The same bound driven the other way.
    pub fn invert(&self) -> Bound {
        Bound {
            way: self.way,
            inverted: !self.inverted,
            nodes: self.nodes.iter().rev().copied().collect(),
        }
    }

    fn same_as(&self, other: &Bound) -> bool {
        self.way == other.way && self.inverted == other.inverted
    }
}

/// A lanelet in one driving direction.
#[derive(Debug, Clone)]
pub struct Directed {
    /// Its cpmx id.
    pub id: LaneletId,
    /// Its left bound.
    pub left: Bound,
    /// Its right bound.
    pub right: Bound,
}

/// What the routing graph says about one directed lanelet.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Relations {
    /// The lanelets following it, in the order of `lanelets`.
    pub following: Vec<LaneletId>,
    /// Its left neighbour.
    pub left: Option<Adjacent>,
    /// Its right neighbour.
    pub right: Option<Adjacent>,
}

/// The relations of every lanelet, in the order given. `lane_changes` gives each way's lane
/// changes in its stored direction (ways missing allow none).
pub fn relations(lanelets: &[Directed], lane_changes: &HashMap<i64, LaneChange>) -> Vec<Relations> {
    // Lanelets by the nodes their bounds start at.
    let mut by_start: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, l) in lanelets.iter().enumerate() {
        if let (Some(&a), Some(&b)) = (l.left.nodes.first(), l.right.nodes.first()) {
            by_start.entry((a, b)).or_default().push(i);
        }
    }
    let mut by_right_way: HashMap<i64, Vec<usize>> = HashMap::new();
    let mut by_left_way: HashMap<i64, Vec<usize>> = HashMap::new();
    for (i, l) in lanelets.iter().enumerate() {
        by_right_way.entry(l.right.way).or_default().push(i);
        by_left_way.entry(l.left.way).or_default().push(i);
    }
    let allows = |bound: &Bound| {
        let change = lane_changes.get(&bound.way).copied().unwrap_or(LaneChange::None);
        if bound.inverted { change.inverted() } else { change }
    };

    lanelets
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let following: Vec<usize> = match (a.left.nodes.last(), a.right.nodes.last()) {
                (Some(&l), Some(&r)) => by_start.get(&(l, r)).cloned().unwrap_or_default(),
                _ => Vec::new(),
            };
            let beside = |candidates: Option<&Vec<usize>>, shares: &dyn Fn(&Directed) -> bool| {
                candidates?
                    .iter()
                    .copied()
                    .find(|&j| j != i && shares(&lanelets[j]) && !following.contains(&j))
            };
            let same = |j: usize, lane_change: bool| Adjacent {
                id: lanelets[j].id,
                direction: DrivingDirection::Same,
                lane_change: Some(lane_change),
            };
            let left = beside(by_right_way.get(&a.left.way), &|b| b.right.same_as(&a.left))
                .map(|j| same(j, allows(&a.left).to_left()))
                .or_else(|| {
                    let oncoming =
                        |b: &Directed| b.left.way == a.left.way && b.left.inverted != a.left.inverted;
                    beside(by_left_way.get(&a.left.way), &oncoming).map(|j| Adjacent {
                        id: lanelets[j].id,
                        direction: DrivingDirection::Opposite,
                        lane_change: Some(false),
                    })
                });
            let right = beside(by_left_way.get(&a.right.way), &|b| b.left.same_as(&a.right))
                .map(|j| same(j, allows(&a.right).to_right()));
            Relations {
                following: following.iter().map(|&j| lanelets[j].id).collect(),
                left,
                right,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bound(way: i64, nodes: &[i64]) -> Bound {
        Bound {
            way,
            inverted: false,
            nodes: nodes.to_vec(),
        }
    }

    /// Two lanes side by side (1 left of 2, sharing way 11), each continued (3, 4), and lanelet
    /// 5 driven against way 10, the left bound of 1.
    fn lanes() -> Vec<Directed> {
        vec![
            Directed {
                id: 1,
                left: bound(10, &[1, 2]),
                right: bound(11, &[3, 4]),
            },
            Directed {
                id: 2,
                left: bound(11, &[3, 4]),
                right: bound(12, &[5, 6]),
            },
            Directed {
                id: 3,
                left: bound(13, &[2, 7]),
                right: bound(14, &[4, 8]),
            },
            Directed {
                id: 4,
                left: bound(14, &[4, 8]),
                right: bound(15, &[6, 9]),
            },
            Directed {
                id: 5,
                left: bound(10, &[1, 2]).invert(),
                right: bound(16, &[20, 21]),
            },
        ]
    }

    #[test]
    fn following_neighbours_and_lane_changes() {
        let changes = HashMap::from([(11, LaneChange::ToRight), (14, LaneChange::Both)]);
        let r = relations(&lanes(), &changes);
        assert_eq!(r[0].following, vec![3]);
        assert_eq!(r[1].following, vec![4]);
        // Way 11 allows changes to the right only: from 1 to 2, not back.
        assert_eq!(r[0].right.map(|a| (a.id, a.lane_change)), Some((2, Some(true))));
        assert_eq!(r[1].left.map(|a| (a.id, a.lane_change)), Some((1, Some(false))));
        assert_eq!(r[2].right.map(|a| (a.id, a.lane_change)), Some((4, Some(true))));
        assert_eq!(r[3].left.map(|a| (a.id, a.lane_change)), Some((3, Some(true))));
        // 5 shares 1's left way the other way round: oncoming, no lane change.
        let oncoming = r[0].left.expect("oncoming");
        assert_eq!((oncoming.id, oncoming.direction), (5, DrivingDirection::Opposite));
        assert_eq!(r[4].left.map(|a| a.id), Some(1));
    }

    #[test]
    fn an_inverted_bound_reads_its_line_type_backwards() {
        // Lane 2 drives way 11 backwards: its left bound is 11 inverted, so a line that allows
        // changes to the right along the way allows them to the left along lane 2.
        let mut ls = lanes();
        ls[1].left = bound(11, &[4, 3]).invert();
        ls[0].right = ls[1].left.clone();
        let changes = HashMap::from([(11, LaneChange::ToRight)]);
        let r = relations(&ls, &changes);
        assert_eq!(r[1].left.map(|a| (a.id, a.lane_change)), Some((1, Some(true))));
        assert_eq!(r[0].right.map(|a| (a.id, a.lane_change)), Some((2, Some(false))));
    }
}
