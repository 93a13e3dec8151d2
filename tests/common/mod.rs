//! Shared by the integration tests: validation of written JSON against the
//! committed schemas (`results/schema/`).

#![allow(dead_code)]

/// Fail with every schema violation of `value` against `results/schema/<schema>`.
pub fn assert_matches_schema(schema: &str, value: &serde_json::Value, what: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("results/schema").join(schema);
    let schema: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let validator = jsonschema::validator_for(&schema).expect("a valid JSON Schema");
    let errors: Vec<String> = validator.iter_errors(value).map(|e| format!("{} at {}", e, e.instance_path())).collect();
    assert!(errors.is_empty(), "{what} does not match {}:\n{}", path.display(), errors.join("\n"));
}
