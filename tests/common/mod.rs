//! Shared by the integration tests: one validated Vulkan context per test
//! binary, and validation of written JSON against the committed schemas
//! (`results/schema/`).

#![allow(dead_code)]

pub mod user_files;

/// Fail with every schema violation of `value` against `results/schema/<schema>`.
pub fn assert_matches_schema(schema: &str, value: &serde_json::Value, what: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("results/schema").join(schema);
    let schema: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let validator = jsonschema::validator_for(&schema).expect("a valid JSON Schema");
    let errors: Vec<String> = validator.iter_errors(value).map(|e| format!("{} at {}", e, e.instance_path())).collect();
    assert!(errors.is_empty(), "{what} does not match {}:\n{}", path.display(), errors.join("\n"));
}

/// One validated context for the whole test binary; runs are serialised
/// because lavapipe already uses every core.
pub fn context() -> std::sync::MutexGuard<'static, std::sync::Arc<volbench::vk::Context>> {
    static CTX: std::sync::OnceLock<std::sync::Mutex<std::sync::Arc<volbench::vk::Context>>> = std::sync::OnceLock::new();
    CTX.get_or_init(|| {
        let ctx = volbench::vk::Context::new(&volbench::vk::ContextDesc { device: None, validation: true }).expect("a Vulkan device (run scripts/setup.sh)");
        std::sync::Mutex::new(ctx)
    })
    .lock()
    .unwrap_or_else(|p| p.into_inner())
}

/// `spec` run on `mesh` with the shared validated context; any validation
/// message fails the test.
pub fn run_mesh(
    mesh: &volbench::mesh::TetMesh,
    tf: &volbench::scene::TransferFunction,
    spec: &str,
    cfg: &volbench::harness::run::RunConfig,
) -> volbench::harness::run::RunOutput {
    let dataset = volbench::harness::datasets::Dataset::from_mesh(mesh.clone(), false, "test".into());
    let spec = volbench::algo::registry::builtin().parse_spec(spec, &[]).expect("spec");
    let ctx = context();
    let out = volbench::harness::run::run(&ctx, &spec, &dataset, tf, cfg).expect("run");
    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
    out
}

/// A NumPy `.npy` (format 1.0) of `dict`, the header dict's text, and `data`.
pub fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
    let mut h = dict.to_string();
    while !(h.len() + 11).is_multiple_of(64) {
        h.push(' ');
    }
    h.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((h.len() as u16).to_le_bytes());
    b.extend(h.as_bytes());
    b.extend(data);
    b
}
