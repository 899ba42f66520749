use super::*;

#[test]
fn the_schema_is_draft_2020_12_and_compiles() {
    let schema = json_schema();
    assert_eq!(schema["$schema"], "https://json-schema.org/draft/2020-12/schema");
    assert!(strict_schema().1.is_some());
}

#[test]
fn typos_find_their_key() {
    let keys = ["repetitions".to_string(), "seed".to_string()];
    assert_eq!(did_you_mean("repetitons", &keys).as_deref(), Some("repetitions"));
    assert_eq!(did_you_mean("zzz", &keys), None);
}

#[test]
fn pointers_read_as_paths() {
    assert_eq!(describe("/policies/1/mlp"), "`policies[1].mlp`");
    assert_eq!(describe(""), "the spec");
}
