//! Maps written by this project, generated in code (`stdlib:NAME`).

use crate::error::MapError;
use crate::map::Map;

/// Names of the built-in maps.
pub fn builtin_names() -> &'static [&'static str] {
    &[]
}

impl Map {
    /// A built-in map by name (see [`builtin_names`]).
    pub fn builtin(name: &str) -> Result<Map, MapError> {
        Err(MapError::UnknownBuiltin(name.to_owned()))
    }
}
