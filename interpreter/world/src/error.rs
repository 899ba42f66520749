//! Typed errors of map loading and reference-path building, each carrying where in the map
//! file the problem sits. Rendering (miette) is the CLI's business, not this module's.

use std::fmt;
use std::path::PathBuf;

use crate::lanelet::LaneletId;

/// A position in a map file: byte offset and 1-based line and column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SourceLocation {
    /// Byte offset from the start of the file.
    pub offset: usize,
    /// 1-based line number.
    pub line: u32,
    /// 1-based column (in characters).
    pub column: u32,
}

impl SourceLocation {
    /// The location of a 1-based line and column (as XML parsers report them) in `text`.
    pub fn from_line_column(text: &str, line: u32, column: u32) -> Self {
        let mut offset = 0;
        for (i, l) in text.split_inclusive('\n').enumerate() {
            if i + 1 == line as usize {
                offset += l
                    .char_indices()
                    .nth(column.saturating_sub(1) as usize)
                    .map_or(l.len(), |(b, _)| b);
                break;
            }
            offset += l.len();
        }
        Self {
            offset: offset.min(text.len()),
            line,
            column,
        }
    }
}

/// Start offsets of the lines of a text, to turn byte offsets into lines and columns fast.
#[derive(Debug, Clone)]
pub struct LineIndex<'a> {
    text: &'a str,
    line_starts: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    /// Indexes `text` (one pass).
    pub fn new(text: &'a str) -> Self {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Self { text, line_starts }
    }

    /// The location of byte `offset` (clamped to the text).
    pub fn locate(&self, offset: usize) -> SourceLocation {
        let offset = offset.min(self.text.len());
        let line = self.line_starts.partition_point(|&s| s <= offset).max(1);
        let start = self.line_starts.get(line - 1).copied().unwrap_or(0);
        let column = self.text.get(start..offset).map_or(0, |s| s.chars().count()) + 1;
        SourceLocation {
            offset,
            line: u32::try_from(line).unwrap_or(u32::MAX),
            column: u32::try_from(column).unwrap_or(u32::MAX),
        }
    }
}

impl fmt::Display for SourceLocation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.line, self.column)
    }
}

/// Why a map could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The map file could not be read.
    #[error("cannot read map file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The text is not well-formed XML.
    #[error("{location}: not XML: {message}")]
    NotXml {
        /// Where the XML parser stopped.
        location: SourceLocation,
        /// The parser's message.
        message: String,
    },
    /// The format could not be detected, or the root element is not the expected one.
    #[error("{location}: {message}")]
    UnknownFormat {
        /// The root element.
        location: SourceLocation,
        /// What was found.
        message: String,
    },
    /// A coordinate is missing, not a number, or not finite.
    #[error("{location}: invalid coordinate: {message}")]
    InvalidCoordinate {
        /// The offending element.
        location: SourceLocation,
        /// What is wrong.
        message: String,
    },
    /// The left and right boundary of a lanelet have different numbers of points.
    #[error("{location}: lanelet {lanelet}: left boundary has {left} points, right boundary {right}")]
    BoundaryLengthMismatch {
        /// The lanelet element.
        location: SourceLocation,
        /// Its id.
        lanelet: LaneletId,
        /// Points of the left boundary.
        left: usize,
        /// Points of the right boundary.
        right: usize,
    },
    /// A boundary has fewer than two points.
    #[error("{location}: lanelet {lanelet}: a boundary needs at least 2 points, found {count}")]
    TooFewPoints {
        /// The boundary element.
        location: SourceLocation,
        /// The lanelet's id.
        lanelet: LaneletId,
        /// Points found.
        count: usize,
    },
    /// A reference names a lanelet (or node, or way) that the file does not define.
    #[error("{location}: {message}")]
    UnknownReference {
        /// The referencing element.
        location: SourceLocation,
        /// What was referenced.
        message: String,
    },
    /// Any other structural problem (missing or invalid id, duplicate id, missing element).
    #[error("{location}: {message}")]
    Malformed {
        /// The offending element.
        location: SourceLocation,
        /// What is wrong.
        message: String,
    },
    /// The map has no lanelets.
    #[error("the map has no lanelets")]
    NoLanelets,
    /// SigmaRL's scenario table has no scenario of that name.
    #[error("SigmaRL's scenario table has no scenario `{name}`; it has {known}")]
    UnknownScenario {
        /// The name asked for.
        name: String,
        /// The names it has (of JOSM maps), comma-separated.
        known: String,
    },
    /// A region name the map does not define.
    #[error("unknown region `{name}`; the map defines: {available}")]
    UnknownRegion {
        /// The requested name.
        name: String,
        /// Comma-separated names the map has.
        available: String,
    },
    /// A built-in map name that does not exist.
    #[error("unknown built-in map `{0}`")]
    UnknownBuiltin(String),
    /// A reference-path problem.
    #[error(transparent)]
    Path(#[from] PathError),
}

/// Why a reference path could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PathError {
    /// A path needs at least one lanelet.
    #[error("reference path {id}: no lanelets given")]
    Empty {
        /// The path id.
        id: usize,
    },
    /// A lanelet id the map does not have.
    #[error("reference path {id}: unknown lanelet {lanelet}")]
    UnknownLanelet {
        /// The path id.
        id: usize,
        /// The lanelet.
        lanelet: LaneletId,
    },
    /// Two consecutive lanelets are not successors.
    #[error("reference path {id}: lanelet {to} is not a successor of lanelet {from}")]
    NotSuccessor {
        /// The path id.
        id: usize,
        /// The earlier lanelet.
        from: LaneletId,
        /// The later lanelet.
        to: LaneletId,
    },
    /// The concatenated own boundaries differ in length, so no centre line exists.
    #[error("reference path {id}: own left boundary has {left} points, right boundary {right}")]
    BoundaryMismatch {
        /// The path id.
        id: usize,
        /// Points of the left boundary.
        left: usize,
        /// Points of the right boundary.
        right: usize,
    },
    /// The path set is not defined for this map (only the CPM Lab map has the SigmaRL sets).
    #[error("path set {set} is only defined for the CPM Lab map")]
    SetUnavailable {
        /// The requested set.
        set: String,
    },
}
