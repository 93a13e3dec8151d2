//! Every uniform block, push-constant block and parameter block the shaders
//! declare agrees with the `#[repr(C)]` struct the Rust side writes into it:
//! the compiled SPIR-V (the same `vk::compile_glsl` the pipelines use) is
//! reflected with `spirq`, and each block's members (nested structs
//! flattened, e.g. `table.tf_lo`) must be the struct's fields at the same
//! offsets and of the same sizes, and the block as large as the struct.
//!
//! Which SPIR-V is checked: every shader under `shaders/` that declares the
//! block or includes (directly or not) the file declaring it. A block's
//! layout changes only with the conditionals inside its own declaration
//! (`#ifdef ADAPTIVE` in `raycast/frame.glsl`); each shader is compiled as
//! its pipelines build it without them, and the variants that turn them
//! on are listed with the block ([`Block::variants`]), the test failing if
//! a conditional in the declaration is left without one. A declaration of a
//! push-constant or uniform block in a file this table does not list fails
//! the test too, so a new block cannot go unchecked.
//!
//! No GPU needed.

use std::collections::BTreeMap;
use std::mem::{offset_of, size_of};

use spirq::ty::Type;
use spirq::var::Variable;
use spirq::ReflectConfig;
use volbench::vk::{compile_glsl, ShaderStage};

/// A leaf member: offset and size in bytes.
type Layout = BTreeMap<String, (usize, usize)>;

/// Which variable of the shader the block is.
#[derive(Debug, Clone, Copy)]
enum Kind {
    PushConstant,
    /// A uniform or storage buffer at (set, binding).
    Buffer(u32, u32),
}

struct Block {
    /// The file under `shaders/` declaring it.
    file: &'static str,
    kind: Kind,
    /// The Rust struct's name (for messages).
    rust: &'static str,
    /// Its size and fields, by the GLSL member each one is.
    size: usize,
    fields: Layout,
    /// Fields of the Rust struct that no member is: layout padding
    /// (`pad_*`), checked to lie where the GLSL layout leaves a gap.
    padding: Layout,
    /// Defines that turn on conditionals inside the declaration, with the
    /// struct the block then matches (size and fields).
    variants: Vec<Variant>,
}

struct Variant {
    shader: &'static str,
    defines: &'static [(&'static str, &'static str)],
    rust: &'static str,
    size: usize,
    fields: Layout,
    padding: Layout,
}

/// `fields!(T; "glsl.member" => rust.path, ...)`: each field's offset
/// (`offset_of!`) and size, by the GLSL member name.
macro_rules! fields {
    ($t:ty; $($glsl:literal => $($path:ident).+),* $(,)?) => {{
        let zero: $t = bytemuck::Zeroable::zeroed();
        let mut m = Layout::new();
        $(
            m.insert($glsl.to_string(), (offset_of!($t, $($path).+), std::mem::size_of_val(&zero.$($path).+)));
        )*
        m
    }};
}

fn blocks() -> Vec<Block> {
    use volbench::algo::adaptive::DecidePush;
    use volbench::algo::cell_projection::device_sort::{PassParams, SortCamera};
    use volbench::algo::tet_mesh::FrameConstants;
    use volbench::algo::raycast::{AdaptiveFrame, Frame, Params};
    use volbench::algo::terrain::compute::{DrawArgs, TessPush};
    use volbench::algo::terrain::Push;
    use volbench::algo::tet_raycast::WalkFrame;
    let raycast_frame = fields!(Frame; "m" => m, "first_group" => first_group, "rows" => rows, "runs" => runs, "light" => light);
    vec![
        Block {
            file: "common/frame.glsl",
            kind: Kind::PushConstant,
            rust: "tet_mesh::FrameConstants",
            size: size_of::<FrameConstants>(),
            fields: fields!(FrameConstants;
                "view_proj" => view_proj, "eye" => eye, "perspective" => perspective, "view_dir" => view_dir,
                "max_segment" => max_segment, "table.tf_lo" => table.tf_lo, "table.tf_inv_range" => table.tf_inv_range,
                "table.tf_entries" => table.tf_entries, "table.table_side" => table.table_side,
                "table.preint_length" => table.preint_length, "distance_clamp" => distance_clamp,
                "plane_ratio_max" => plane_ratio_max, "edge_eps" => edge_eps),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "tet_raycast/frame.glsl",
            kind: Kind::PushConstant,
            rust: "tet_raycast::WalkFrame",
            size: size_of::<WalkFrame>(),
            fields: fields!(WalkFrame;
                "eye" => eye, "perspective" => perspective, "forward" => forward, "near" => near, "right" => right,
                "far" => far, "up" => up, "ert" => ert, "table.tf_lo" => table.tf_lo,
                "table.tf_inv_range" => table.tf_inv_range, "table.tf_entries" => table.tf_entries,
                "table.table_side" => table.table_side, "table.preint_length" => table.preint_length,
                "entry_tol" => entry_tol, "step_budget" => step_budget, "stall_limit" => stall_limit, "rect" => rect,
                "rows" => rows, "runs" => runs, "cast_step" => cast_step),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "raycast/params.glsl",
            kind: Kind::Buffer(0, 0),
            rust: "raycast::Params",
            size: size_of::<Params>(),
            fields: fields!(Params;
                "box_max" => box_max, "brick" => brick, "inv_dims" => inv_dims, "table_entries" => table_entries,
                "spacing" => spacing, "step" => step, "tf_scale" => tf_scale, "tf_offset" => tf_offset, "ert" => ert,
                "preint_length" => preint_length, "brick_grid" => brick_grid, "ambient" => ambient, "diffuse" => diffuse,
                "specular" => specular, "shininess" => shininess),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "raycast/frame.glsl",
            kind: Kind::PushConstant,
            rust: "raycast::Frame",
            size: size_of::<Frame>(),
            fields: raycast_frame,
            padding: Layout::new(),
            variants: vec![Variant {
                shader: "raycast/march.comp",
                defines: &[("ADAPTIVE", "1"), ("ADAPTIVE_SET", "2")],
                rust: "raycast::AdaptiveFrame",
                size: size_of::<AdaptiveFrame>(),
                fields: fields!(AdaptiveFrame;
                    "m" => frame.m, "first_group" => frame.first_group, "rows" => frame.rows, "runs" => frame.runs,
                    "light" => frame.light, "close" => close, "rect" => rect, "cast_step" => cast_step),
                padding: Layout::new(),
            }],
        },
        Block {
            file: "terrain/common.glsl",
            kind: Kind::PushConstant,
            rust: "terrain::Push",
            size: size_of::<Push>(),
            fields: fields!(Push;
                "view_proj" => view_proj, "tint" => tint, "tint_mix" => tint_mix, "light" => light,
                "height_lo" => height_lo, "height_hi" => height_hi, "grid_base" => grid_base, "grid_width" => grid_width),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "terrain/pc.comp",
            kind: Kind::PushConstant,
            rust: "terrain::compute::TessPush",
            size: size_of::<TessPush>(),
            fields: fields!(TessPush; "count" => count, "grid_base" => grid_base, "grid_width" => grid_width, "capacity" => capacity),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "terrain/pc.comp",
            kind: Kind::Buffer(0, 4),
            rust: "terrain::compute::DrawArgs",
            size: size_of::<DrawArgs>(),
            fields: fields!(DrawArgs;
                "index_count" => index_count, "instance_count" => instance_count, "first_index" => first_index,
                "vertex_offset" => vertex_offset, "first_instance" => first_instance, "errors" => errors),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "common/adaptive_decide.comp",
            kind: Kind::PushConstant,
            rust: "adaptive::DecidePush",
            size: size_of::<DecidePush>(),
            fields: fields!(DecidePush;
                "rect" => rect, "block_size" => block_size, "rows" => rows, "runs" => runs,
                "silhouettes" => silhouettes, "tol" => tol, "straight" => straight),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "cell_projection/sort_keys.comp",
            kind: Kind::PushConstant,
            rust: "device_sort::SortCamera",
            size: size_of::<SortCamera>(),
            fields: fields!(SortCamera; "eye" => eye, "perspective" => perspective, "dir" => dir),
            padding: Layout::new(),
            variants: vec![],
        },
        Block {
            file: "cell_projection/radix_sort.glsl",
            kind: Kind::Buffer(0, 0),
            rust: "device_sort::PassParams",
            size: size_of::<PassParams>(),
            fields: fields!(PassParams; "n" => n, "groups" => groups, "shift" => shift),
            padding: Layout::new(),
            variants: vec![],
        },
    ]
}

/// The `#include`d files of a source (paths under `shaders/`).
fn includes(text: &str) -> impl Iterator<Item = &str> {
    text.lines().filter_map(|l| l.trim().strip_prefix("#include \"")?.strip_suffix('"'))
}

/// Whether `path` is `file` or includes it, directly or not.
fn uses(path: &str, file: &str) -> bool {
    path == file || volbench::shaders::source(path).is_some_and(|t| includes(t).any(|i| uses(i, file)))
}

/// The leaf members of a reflected struct, nested structs flattened with a
/// dot, at their offsets from the block's start; members are named by
/// `names` (the same struct reflected from an unoptimised compile: the
/// pipelines' optimised SPIR-V carries no member names), matched by index.
fn flatten(ty: &Type, names: &Type, prefix: &str, base: usize, out: &mut Layout) {
    let (Type::Struct(s), Type::Struct(n)) = (ty, names) else { panic!("{prefix}: not a struct: {ty:?}") };
    assert_eq!(s.members.len(), n.members.len(), "{prefix}: the optimised and the named compile differ");
    for (m, named) in s.members.iter().zip(&n.members) {
        let name = named.name.clone().unwrap_or_else(|| panic!("{prefix}: a member without a name"));
        let name = if prefix.is_empty() { name } else { format!("{prefix}.{name}") };
        let offset = base + m.offset.unwrap_or_else(|| panic!("{name}: no offset"));
        assert_eq!(m.offset, named.offset, "{name}: the optimised and the named compile differ");
        match &m.ty {
            Type::Struct(_) => flatten(&m.ty, &named.ty, &name, offset, out),
            t => {
                let size = t.nbyte().unwrap_or_else(|| panic!("{name}: no size"));
                out.insert(name, (offset, size));
            }
        }
    }
}

/// `shader` compiled as `vk::compile_glsl` compiles it, but unoptimised
/// (debug names kept).
fn compile_named(shader: &str, stage: ShaderStage, defines: &[(&str, &str)]) -> Vec<u32> {
    let kind = match stage {
        ShaderStage::Vertex => shaderc::ShaderKind::Vertex,
        ShaderStage::Fragment => shaderc::ShaderKind::Fragment,
        ShaderStage::Geometry => shaderc::ShaderKind::Geometry,
        ShaderStage::Compute => shaderc::ShaderKind::Compute,
    };
    let compiler = shaderc::Compiler::new().expect("shaderc");
    let mut options = shaderc::CompileOptions::new().expect("shaderc options");
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_3 as u32);
    options.set_optimization_level(shaderc::OptimizationLevel::Zero);
    for (k, v) in defines {
        options.add_macro_definition(k, Some(v));
    }
    options.set_include_callback(|requested, _, _, _| match volbench::shaders::source(requested) {
        Some(text) => Ok(shaderc::ResolvedInclude { resolved_name: format!("shaders/{requested}"), content: text.to_string() }),
        None => Err(format!("shaders/{requested}: include not found")),
    });
    let source = volbench::shaders::source(shader).expect("the shader");
    compiler.compile_into_spirv(source, kind, shader, "main", Some(&options)).unwrap_or_else(|e| panic!("{shader}: {e}")).as_binary().to_vec()
}

/// The type of block `kind` in SPIR-V `spv`.
fn block_type(shader: &str, spv: Vec<u32>, kind: Kind) -> Option<Type> {
    let entries = ReflectConfig::new().spv(spv).ref_all_rscs(true).reflect().unwrap_or_else(|e| panic!("{shader}: reflecting: {e:?}"));
    entries.iter().flat_map(|e| &e.vars).find_map(|var| match (kind, var) {
        (Kind::PushConstant, Variable::PushConstant { ty, .. }) => Some(ty.clone()),
        (Kind::Buffer(set, binding), Variable::Descriptor { desc_bind, ty, .. }) if desc_bind.set() == set && desc_bind.bind() == binding => {
            Some(ty.clone())
        }
        _ => None,
    })
}

/// The block `kind` in the SPIR-V of `shader` compiled with `defines` (the
/// pipelines' compile, `vk::compile_glsl`).
fn reflect(shader: &str, defines: &[(&str, &str)], kind: Kind) -> Option<Layout> {
    let stage = ShaderStage::from_path(shader).unwrap_or_else(|| panic!("{shader}: unknown stage"));
    let spv = compile_glsl(shader, stage, defines, &volbench::shaders::source).unwrap_or_else(|e| panic!("{e}"));
    let ty = block_type(shader, spv, kind)?;
    let names = block_type(shader, compile_named(shader, stage, defines), kind).expect("the block in the named compile");
    let mut layout = Layout::new();
    flatten(&ty, &names, "", 0, &mut layout);
    Some(layout)
}

/// The block's size from its members (the end of the last one).
fn block_size(layout: &Layout) -> usize {
    layout.values().map(|(o, s)| o + s).max().unwrap_or(0)
}

/// The Rust side (`fields`, `padding`, `size`) against a reflected block;
/// every disagreement as a line.
fn disagreements(what: &str, rust: &str, size: usize, fields: &Layout, padding: &Layout, glsl: &Layout) -> Vec<String> {
    let mut out = Vec::new();
    for (name, (offset, len)) in glsl {
        match fields.get(name) {
            None => out.push(format!("{what}: member `{name}` (offset {offset}, {len} bytes) has no field in {rust}")),
            Some(&(o, l)) if (o, l) != (*offset, *len) => {
                out.push(format!("{what}: `{name}` is at offset {offset} ({len} bytes) in GLSL, {o} ({l} bytes) in {rust}"))
            }
            _ => {}
        }
    }
    for name in fields.keys().filter(|n| !glsl.contains_key(*n)) {
        out.push(format!("{what}: {rust} field for `{name}` is no member of the block"));
    }
    // Padding fields lie where no member does.
    for (name, (o, l)) in padding {
        if glsl.values().any(|(mo, ml)| o < &(mo + ml) && mo < &(o + l)) {
            out.push(format!("{what}: {rust}'s padding `{name}` overlaps a member"));
        }
    }
    // Every byte of the struct is a member's or a named padding's, and the
    // block ends where the struct does.
    let covered: usize = fields.values().chain(padding.values()).map(|(_, l)| l).sum();
    if covered != size {
        out.push(format!("{what}: {rust}'s fields cover {covered} of its {size} bytes"));
    }
    if block_size(glsl) != size {
        out.push(format!("{what}: the block is {} bytes, {rust} {size}", block_size(glsl)));
    }
    out
}

/// The macros a block's declaration tests (`#ifdef X`, `#if defined(X)`).
fn conditionals(file: &str, kind: Kind) -> Vec<String> {
    let text = volbench::shaders::source(file).unwrap_or_else(|| panic!("{file}: no such file"));
    let start = match kind {
        Kind::PushConstant => text.find("layout(push_constant)"),
        Kind::Buffer(set, binding) => text.find(&format!("set = {set}, binding = {binding})")),
    }
    .unwrap_or_else(|| panic!("{file}: no declaration of the block"));
    let end = start + text[start..].find("};").or_else(|| text[start..].find("} ")).expect("the block's end");
    text[start..end]
        .lines()
        .filter_map(|l| {
            let l = l.trim();
            l.strip_prefix("#ifdef ").or_else(|| l.strip_prefix("#ifndef ")).or_else(|| l.strip_prefix("#if defined(").map(|r| r.trim_end_matches(')')))
        })
        .map(|m| m.trim().to_string())
        .collect()
}

#[test]
fn every_block_agrees_with_its_rust_struct() {
    let mut problems = Vec::new();
    let mut checked = 0;
    for block in blocks() {
        let shaders: Vec<&str> = volbench::shaders::all_entry_points().filter(|p| uses(p, block.file)).collect();
        assert!(!shaders.is_empty(), "{}: no shader uses it", block.file);
        for shader in &shaders {
            let what = format!("{} in {shader}", block.file);
            let glsl = reflect(shader, &[], block.kind).unwrap_or_else(|| panic!("{what}: the block is not in the SPIR-V"));
            problems.extend(disagreements(&what, block.rust, block.size, &block.fields, &block.padding, &glsl));
            checked += 1;
        }
        for v in &block.variants {
            assert!(shaders.contains(&v.shader), "{}: variant shader {} does not use it", block.file, v.shader);
            let what = format!("{} in {} with {:?}", block.file, v.shader, v.defines);
            let glsl = reflect(v.shader, v.defines, block.kind).unwrap_or_else(|| panic!("{what}: the block is not in the SPIR-V"));
            problems.extend(disagreements(&what, v.rust, v.size, &v.fields, &v.padding, &glsl));
            checked += 1;
        }
        for m in conditionals(block.file, block.kind) {
            if !block.variants.iter().any(|v| v.defines.iter().any(|(k, _)| *k == m)) {
                problems.push(format!("{}: the declaration tests {m}, and no variant defines it", block.file));
            }
        }
    }
    assert!(problems.is_empty(), "{} disagreements:\n{}", problems.len(), problems.join("\n"));
    eprintln!("{checked} compiled blocks agree with their Rust structs");
}

#[test]
fn every_push_constant_and_uniform_block_is_checked() {
    let listed: Vec<&str> = blocks().iter().map(|b| b.file).collect();
    let mut unlisted = Vec::new();
    for path in volbench::shaders::all_paths() {
        let text = volbench::shaders::source(path).unwrap();
        for (i, line) in text.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            let uniform_block = code.contains(" uniform ") && code.trim_end().ends_with('{');
            if (code.contains("push_constant") || uniform_block) && !listed.contains(&path) {
                unlisted.push(format!("shaders/{path}:{}: {}", i + 1, line.trim()));
            }
        }
    }
    assert!(unlisted.is_empty(), "blocks no Rust struct is checked against (add them to blocks()):\n{}", unlisted.join("\n"));
}

/// The check can fail: the cell-projection frame with one field moved by a
/// float (as a struct reordered on one side only would be) and a size one
/// float short are both reported against the compiled shader.
#[test]
fn a_wrong_offset_or_size_is_reported() {
    let block = blocks().into_iter().next().expect("the cell-projection frame");
    assert_eq!(block.file, "common/frame.glsl");
    let glsl = reflect("cell_projection/vicp.vert", &[], block.kind).expect("the block");
    assert!(disagreements("frame", block.rust, block.size, &block.fields, &block.padding, &glsl).is_empty());
    let mut moved = block.fields.clone();
    moved.get_mut("table.table_side").unwrap().0 += 4;
    let found = disagreements("frame", block.rust, block.size, &moved, &block.padding, &glsl);
    assert!(found.iter().any(|l| l.contains("`table.table_side` is at offset")), "{found:?}");
    let found = disagreements("frame", block.rust, block.size - 4, &block.fields, &block.padding, &glsl);
    assert!(found.iter().any(|l| l.contains("the block is 128 bytes")), "{found:?}");
}
