//! The CPM Lab map's reference paths as SigmaRL defines them. These tables are part of
//! SigmaRL's *code*, not of the map file: `sigmarl/parse_xml.py` (`ParseXML.__init__`:
//! `_reference_paths_ids`; `_get_reference_paths`: `path_to_loop`,
//! `lanelets_share_same_boundaries_list`, `path_intersection`, `path_merge_in`,
//! `path_merge_out`) at SigmaRL commit `4c8032d`, as dumped in the reference data
//! (`cpm_reference_paths.json`). This module also recognises the CPM Lab map.

use crate::lanelet::{Lanelet, LaneletId};

/// The CommonRoad `benchmarkID` of SigmaRL's `cpm.xml`.
pub const BENCHMARK_ID: &str = "C-ZAM_AC-1_1_T-1";

/// Number of lanelets of the CPM Lab map (ids 1..=104).
pub const LANELET_COUNT: usize = 104;

/// World bounds SigmaRL hard-codes for the CPM Lab (`SCENARIOS["CPM_entire"]`): x and y
/// ranges [m].
pub const BOUNDS_M: ([f64; 2], [f64; 2]) = ([0.0, 4.5], [0.0, 4.0]);

/// The 7 lanelet loops (`_reference_paths_ids`, loops 1..7). Each loop is closed implicitly.
pub const LOOPS: [&[LaneletId]; 7] = [
    &[4, 6, 8, 60, 58, 56, 54, 80, 82, 84, 86, 34, 32, 30, 28, 2],
    &[1, 3, 23, 10, 12, 17, 43, 38, 36, 49, 29, 27],
    &[64, 62, 75, 55, 53, 79, 81, 101, 88, 90, 95, 69],
    &[40, 45, 97, 92, 94, 100, 83, 85, 33, 31, 48, 42],
    &[5, 7, 59, 57, 74, 68, 66, 71, 19, 14, 16, 22],
    &[41, 39, 20, 63, 61, 57, 55, 67, 65, 98, 37, 35, 31, 29],
    &[3, 5, 9, 11, 72, 91, 93, 81, 83, 87, 89, 46, 13, 15],
];

/// `path_to_loop`: for `cpm_entire` path index `i` (0-based; SigmaRL's path id is `i + 1`),
/// the loop number (1..7) and the lanelet the path starts at.
pub const PATH_TO_LOOP: [(usize, LaneletId); 40] = [
    (1, 4),
    (2, 1),
    (3, 64),
    (4, 42),
    (5, 22),
    (6, 39),
    (7, 15),
    (1, 8),
    (2, 10),
    (3, 75),
    (4, 45),
    (5, 59),
    (6, 61),
    (7, 5),
    (1, 58),
    (2, 17),
    (3, 79),
    (4, 92),
    (5, 68),
    (6, 55),
    (7, 11),
    (1, 54),
    (2, 38),
    (3, 88),
    (4, 100),
    (5, 19),
    (6, 65),
    (7, 93),
    (1, 82),
    (2, 49),
    (3, 95),
    (4, 33),
    (5, 14),
    (6, 35),
    (7, 83),
    (1, 86),
    (6, 29),
    (7, 89),
    (1, 32),
    (1, 28),
];

/// `lanelets_share_same_boundaries_list`: lanelets side by side in the same direction, from
/// left to right.
pub const BOUNDARY_SHARING_GROUPS: [&[LaneletId]; 48] = [
    &[4, 3, 22],
    &[6, 5, 23],
    &[8, 7],
    &[60, 59],
    &[58, 57, 75],
    &[56, 55, 74],
    &[54, 53],
    &[80, 79],
    &[82, 81, 100],
    &[84, 83, 101],
    &[86, 85],
    &[34, 33],
    &[32, 31, 49],
    &[30, 29, 48],
    &[28, 27],
    &[2, 1],
    &[13, 14],
    &[15, 16],
    &[9, 10],
    &[11, 12],
    &[63, 64],
    &[61, 62],
    &[67, 68],
    &[65, 66],
    &[91, 92],
    &[93, 94],
    &[87, 88],
    &[89, 90],
    &[37, 38],
    &[35, 36],
    &[41, 42],
    &[39, 40],
    &[25, 18],
    &[26, 17],
    &[52, 43],
    &[72, 73],
    &[51, 44],
    &[50, 45],
    &[102, 97],
    &[20, 21],
    &[103, 96],
    &[104, 95],
    &[78, 69],
    &[46, 47],
    &[77, 70],
    &[76, 71],
    &[24, 19],
    &[98, 99],
];

/// `path_intersection`: the 24 open paths of the `cpm_mixed` intersection set.
pub const INTERSECTION_PATHS: [&[LaneletId]; 24] = [
    &[11, 25, 13],
    &[11, 26, 52, 37],
    &[11, 72, 91],
    &[12, 18, 14],
    &[12, 17, 43, 38],
    &[12, 73, 92],
    &[39, 51, 37],
    &[39, 50, 102, 91],
    &[39, 20, 63],
    &[40, 44, 38],
    &[40, 45, 97, 92],
    &[40, 21, 64],
    &[89, 103, 91],
    &[89, 104, 78, 63],
    &[89, 46, 13],
    &[90, 96, 92],
    &[90, 95, 69, 64],
    &[90, 47, 14],
    &[65, 77, 63],
    &[65, 76, 24, 13],
    &[65, 98, 37],
    &[66, 70, 64],
    &[66, 71, 19, 14],
    &[66, 99, 38],
];

/// `path_merge_in`: the 4 merge-in paths.
pub const MERGE_IN_PATHS: [&[LaneletId]; 4] = [&[34, 32], &[33, 31], &[35, 31], &[36, 49]];

/// `path_merge_out`: the 4 merge-out paths.
pub const MERGE_OUT_PATHS: [&[LaneletId]; 4] = [&[6, 8], &[5, 7], &[5, 9], &[23, 10]];

/// `_intersection_outer_boundary_ids`: lanelets whose right boundaries outline the
/// intersection (used by SigmaRL only for drawing).
pub const INTERSECTION_OUTER_BOUNDARY_LANELETS: [LaneletId; 4] = [18, 44, 96, 70];

/// The lanelets of `cpm_entire` path `index` (0..40): its loop rotated to start at the
/// path's starting lanelet (`loop[i:] + loop[:i]`).
pub fn entire_path_lanelets(index: usize) -> Option<Vec<LaneletId>> {
    let &(loop_number, start) = PATH_TO_LOOP.get(index)?;
    let lanelets = LOOPS.get(loop_number.checked_sub(1)?)?;
    let i = lanelets.iter().position(|&l| l == start)?;
    Some([&lanelets[i..], &lanelets[..i]].concat())
}

/// Whether `lanelets` is the CPM Lab map: lanelet ids exactly 1..=104 in file order and every
/// consecutive pair of SigmaRL's loops and open paths is a successor relation of the file.
/// (The `benchmarkID` is not required, so a renamed copy is still recognised; a different map
/// with the same ids fails the topology check.)
pub fn is_cpm_lab(lanelets: &[Lanelet]) -> bool {
    if lanelets.len() != LANELET_COUNT
        || !lanelets
            .iter()
            .zip(1..)
            .all(|(l, id): (&Lanelet, LaneletId)| l.id == id)
    {
        return false;
    }
    let is_successor = |a: LaneletId, b: LaneletId| {
        lanelets
            .get(a as usize - 1)
            .is_some_and(|l| l.successors.contains(&b))
    };
    let loops_ok = LOOPS.iter().all(|lp| {
        lp.iter()
            .zip(lp.iter().cycle().skip(1))
            .all(|(&a, &b)| is_successor(a, b))
    });
    let open_ok = INTERSECTION_PATHS
        .iter()
        .chain(&MERGE_IN_PATHS)
        .chain(&MERGE_OUT_PATHS)
        .all(|p| p.windows(2).all(|w| is_successor(w[0], w[1])));
    loops_ok && open_ok
}
