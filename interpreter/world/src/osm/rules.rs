//! The traffic rules cpmx reads Lanelet2 maps with: Lanelet2's German rules for the
//! participant `vehicle` (`lanelet2_traffic_rules`' `GermanVehicle`, what
//! `traffic_rules.create(Locations.Germany, Participants.Vehicle)` gives), the rules its routing
//! graph is built with. They decide which lanelets a vehicle may pass, which it may also drive
//! against their bounds' direction, and across which bounds it may change lanes.
//!
//! Tags are read as Lanelet2 reads them: a repeated key keeps its last value; a boolean is
//! `yes`, `true` or `1`, or `no`, `false` or `0` (anything else is no value); keys are looked up
//! in sorted order where Lanelet2's overrides (`participant:...`, `one_way:...`) search them.

use std::collections::BTreeMap;

/// The participant the rules are for, as Lanelet2 names it.
pub const PARTICIPANT: &str = "vehicle";

/// An element's tags, keys sorted, the last value of a repeated key kept.
pub type Tags = BTreeMap<String, String>;

/// Lanelet2's `Attribute::asBool`.
fn as_bool(value: &str) -> Option<bool> {
    match value {
        "1" | "true" | "yes" => Some(true),
        "0" | "false" | "no" => Some(false),
        _ => None,
    }
}

/// Lanelet2's override lookup (`getOverride`): the first key in sorted order that is at least
/// as long as `prefix` and that `wanted` starts with, as a boolean (`default` when it has none).
fn override_value(tags: &Tags, prefix: &str, wanted: &str, default: bool) -> bool {
    tags.iter()
        .find(|(k, _)| k.len() >= prefix.len() && wanted.starts_with(k.as_str()))
        .map_or(default, |(_, v)| as_bool(v).unwrap_or(default))
}

/// Whether any key starts with `prefix` (`hasOverride`).
fn has_override(tags: &Tags, prefix: &str) -> bool {
    tags.keys().any(|k| k.starts_with(prefix))
}

/// Whether a vehicle may pass a lanelet in its bounds' direction (`GenericTrafficRules::canPass`
/// for a lanelet that is not inverted): a `participant:*` tag decides when there is one
/// (`participant:vehicle`; a tag for a kind of vehicle such as `participant:vehicle:car` does not
/// speak for every vehicle), otherwise the subtype: no subtype, `road`, `highway`,
/// `play_street` and `exit` are for vehicles; every other subtype, known or not, is not.
pub fn passable(tags: &Tags) -> bool {
    if has_override(tags, "participant") {
        return override_value(tags, "participant", &format!("participant:{PARTICIPANT}"), false);
    }
    matches!(
        tags.get("subtype").map_or("", String::as_str),
        "" | "road" | "highway" | "play_street" | "exit"
    )
}

/// Whether a vehicle may also drive a passable lanelet against its bounds' direction
/// (`isDrivingDir` of the inverted lanelet): `one_way` when it is a boolean (`one_way=no`),
/// else an override for vehicles (`one_way:vehicle=no`; when some `one_way...` key exists but
/// none applies, or its value is no boolean, the lanelet is one-way), else one-way.
pub fn two_way(tags: &Tags) -> bool {
    if let Some(one_way) = tags.get("one_way").and_then(|v| as_bool(v)) {
        return !one_way;
    }
    if has_override(tags, "one_way") {
        return !override_value(tags, "one_way", &format!("one_way:{PARTICIPANT}"), true);
    }
    false
}

/// Which lane changes a bound allows, relative to the bound's stored direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneChange {
    /// None.
    None,
    /// From its right side to its left side only.
    ToLeft,
    /// From its left side to its right side only.
    ToRight,
    /// Both ways.
    Both,
}

impl LaneChange {
    /// The same changes seen along the bound run backwards.
    pub fn inverted(self) -> Self {
        match self {
            LaneChange::ToLeft => LaneChange::ToRight,
            LaneChange::ToRight => LaneChange::ToLeft,
            other => other,
        }
    }

    /// Whether a change to the left across the bound is allowed.
    pub fn to_left(self) -> bool {
        matches!(self, LaneChange::ToLeft | LaneChange::Both)
    }

    /// Whether a change to the right across the bound is allowed.
    pub fn to_right(self) -> bool {
        matches!(self, LaneChange::ToRight | LaneChange::Both)
    }
}

/// The lane changes a way allows in its stored direction (`laneChangeType`, virtual lines not
/// passable): `lane_change`, `lane_change:left` and `lane_change:right` tags when they decide,
/// else the line type: a `line_thin` or `line_thick` that is `dashed` allows both,
/// `dashed_solid` only to the right, `solid_dashed` only to the left; everything else
/// (`solid`, `solid_solid`, `virtual`, curbstones, ...) none.
pub fn lane_change(tags: &Tags) -> LaneChange {
    let flag = |k: &str| tags.get(k).map(|v| as_bool(v).unwrap_or(false));
    if let Some(both) = flag("lane_change") {
        return if both { LaneChange::Both } else { LaneChange::None };
    }
    if flag("lane_change:left") == Some(true) {
        return if flag("lane_change:right") == Some(true) {
            LaneChange::Both
        } else {
            LaneChange::ToLeft
        };
    }
    if let Some(right) = flag("lane_change:right") {
        return if right {
            LaneChange::ToRight
        } else {
            LaneChange::None
        };
    }
    let kind = tags.get("type").map_or("", String::as_str);
    if !matches!(kind, "line_thin" | "line_thick") {
        return LaneChange::None;
    }
    match tags.get("subtype").map_or("", String::as_str) {
        "dashed" => LaneChange::Both,
        "dashed_solid" => LaneChange::ToRight,
        "solid_dashed" => LaneChange::ToLeft,
        _ => LaneChange::None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tags(pairs: &[(&str, &str)]) -> Tags {
        pairs
            .iter()
            .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
            .collect()
    }

    #[test]
    fn vehicles_pass_roads_by_subtype_unless_a_participant_tag_says() {
        assert!(passable(&tags(&[])));
        assert!(passable(&tags(&[("subtype", "")])));
        for s in ["road", "highway", "play_street", "exit"] {
            assert!(passable(&tags(&[("subtype", s)])), "{s}");
        }
        for s in [
            "crosswalk",
            "walkway",
            "bicycle_lane",
            "bus_lane",
            "emergency_lane",
            "parking",
        ] {
            assert!(!passable(&tags(&[("subtype", s)])), "{s}");
        }
        assert!(passable(&tags(&[
            ("subtype", "bus_lane"),
            ("participant:vehicle", "yes")
        ])));
        assert!(!passable(&tags(&[
            ("subtype", "road"),
            ("participant:vehicle", "no")
        ])));
        // A tag for cars only does not let every vehicle pass; an unknown value is no.
        assert!(!passable(&tags(&[("participant:vehicle:car", "yes")])));
        assert!(!passable(&tags(&[("participant:vehicle", "maybe")])));
        assert!(!passable(&tags(&[
            ("subtype", "road"),
            ("participant:pedestrian", "yes")
        ])));
    }

    #[test]
    fn one_way_unless_a_boolean_or_an_override_says_otherwise() {
        assert!(!two_way(&tags(&[])));
        assert!(two_way(&tags(&[("one_way", "no")])));
        assert!(two_way(&tags(&[("one_way", "0")])));
        assert!(!two_way(&tags(&[("one_way", "yes")])));
        assert!(!two_way(&tags(&[("one_way", "No")])));
        assert!(two_way(&tags(&[("one_way:vehicle", "no")])));
        assert!(!two_way(&tags(&[("one_way:vehicle:car", "no")])));
        assert!(!two_way(&tags(&[("one_way:bicycle", "no")])));
    }

    #[test]
    fn lane_changes_by_line_type_and_explicit_tags() {
        let line = |t: &str, s: &str| lane_change(&tags(&[("type", t), ("subtype", s)]));
        assert_eq!(line("line_thin", "dashed"), LaneChange::Both);
        assert_eq!(line("line_thick", "dashed"), LaneChange::Both);
        assert_eq!(line("line_thin", "dashed_solid"), LaneChange::ToRight);
        assert_eq!(line("line_thin", "solid_dashed"), LaneChange::ToLeft);
        assert_eq!(line("line_thin", "solid"), LaneChange::None);
        assert_eq!(line("virtual", ""), LaneChange::None);
        assert_eq!(line("curbstone", "dashed"), LaneChange::None);
        let explicit = |pairs: &[(&str, &str)]| lane_change(&tags(pairs));
        assert_eq!(
            explicit(&[
                ("type", "line_thin"),
                ("subtype", "solid"),
                ("lane_change", "yes")
            ]),
            LaneChange::Both
        );
        assert_eq!(
            explicit(&[
                ("type", "line_thin"),
                ("subtype", "dashed"),
                ("lane_change", "no")
            ]),
            LaneChange::None
        );
        assert_eq!(explicit(&[("lane_change:left", "yes")]), LaneChange::ToLeft);
        assert_eq!(
            explicit(&[("lane_change:left", "yes"), ("lane_change:right", "yes")]),
            LaneChange::Both
        );
        // `lane_change:left=no` alone does not decide: the line type does.
        assert_eq!(
            explicit(&[
                ("type", "line_thin"),
                ("subtype", "dashed"),
                ("lane_change:left", "no")
            ]),
            LaneChange::Both
        );
        assert_eq!(
            explicit(&[
                ("lane_change:right", "no"),
                ("type", "line_thin"),
                ("subtype", "dashed")
            ]),
            LaneChange::None
        );
        assert_eq!(LaneChange::ToLeft.inverted(), LaneChange::ToRight);
    }
}
