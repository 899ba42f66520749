//! How a preset-taking field appears in the schema: a `stdlib:NAME` string, an inline object
//! that `extends` a preset and overrides some of its fields, or the whole object inline.

use std::borrow::Cow;

use schemars::{JsonSchema, Schema, SchemaGenerator, json_schema};

/// Schema-only stand-in for a field of type `T` that also accepts `stdlib:NAME`.
///
/// The schema carries the marker `x-cpmx-preset: true`; cpmx's own validation runs after
/// expansion and replaces each marked schema by its inline branch (`crate::schema`).
pub struct PresetOr<T>(std::marker::PhantomData<T>);

/// The pattern of a standard-library reference.
pub const STDLIB_PATTERN: &str = "^stdlib:[a-z0-9][a-z0-9-]*$";

impl<T: JsonSchema> JsonSchema for PresetOr<T> {
    fn schema_name() -> Cow<'static, str> {
        format!("PresetOr{}", T::schema_name()).into()
    }

    fn json_schema(generator: &mut SchemaGenerator) -> Schema {
        let inline = generator.subschema_for::<T>();
        json_schema!({
            "x-cpmx-preset": true,
            "anyOf": [
                inline,
                {
                    "type": "string",
                    "pattern": STDLIB_PATTERN,
                    "description": "A preset of the standard library, e.g. `stdlib:mu-car`."
                },
                {
                    "type": "object",
                    "required": ["extends"],
                    "properties": {
                        "extends": {
                            "type": "string",
                            "pattern": STDLIB_PATTERN,
                            "description": "The preset whose fields this object overrides."
                        }
                    },
                    "description": "A preset with some fields overridden: `{extends: stdlib:NAME, field: value}`."
                }
            ]
        })
    }
}
