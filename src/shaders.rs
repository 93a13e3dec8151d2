//! The GLSL sources of `shaders/`, embedded in the binary so that it runs
//! from anywhere; compiled at run time by `vk::compile_glsl`.

const SOURCES: &[(&str, &str)] = &[
    ("common/frame.glsl", include_str!("../shaders/common/frame.glsl")),
    ("common/integrate.glsl", include_str!("../shaders/common/integrate.glsl")),
    ("common/exit.glsl", include_str!("../shaders/common/exit.glsl")),
    ("common/dispatch.glsl", include_str!("../shaders/common/dispatch.glsl")),
    ("common/clip.glsl", include_str!("../shaders/common/clip.glsl")),
    ("cell_projection/vicp.vert", include_str!("../shaders/cell_projection/vicp.vert")),
    ("cell_projection/vicp.frag", include_str!("../shaders/cell_projection/vicp.frag")),
    ("cell_projection/record.glsl", include_str!("../shaders/cell_projection/record.glsl")),
    ("cell_projection/known_exits_io.glsl", include_str!("../shaders/cell_projection/known_exits_io.glsl")),
    ("cell_projection/stored_cell.glsl", include_str!("../shaders/cell_projection/stored_cell.glsl")),
    ("cell_projection/pt_composite.comp", include_str!("../shaders/cell_projection/pt_composite.comp")),
    ("cell_projection/balanced.vert", include_str!("../shaders/cell_projection/balanced.vert")),
    ("cell_projection/resident.vert", include_str!("../shaders/cell_projection/resident.vert")),
    ("cell_projection/balanced.frag", include_str!("../shaders/cell_projection/balanced.frag")),
    ("cell_projection/atfs.vert", include_str!("../shaders/cell_projection/atfs.vert")),
    ("cell_projection/atfs.frag", include_str!("../shaders/cell_projection/atfs.frag")),
    ("cell_projection/atfs.glsl", include_str!("../shaders/cell_projection/atfs.glsl")),
    ("cell_projection/cap.vert", include_str!("../shaders/cell_projection/cap.vert")),
    ("cell_projection/cap.frag", include_str!("../shaders/cell_projection/cap.frag")),
    ("cell_projection/cap_vert.glsl", include_str!("../shaders/cell_projection/cap_vert.glsl")),
    ("cell_projection/cap_frag.glsl", include_str!("../shaders/cell_projection/cap_frag.glsl")),
    ("cell_projection/cap_pieces.vert", include_str!("../shaders/cell_projection/cap_pieces.vert")),
    ("cell_projection/cap_pieces.frag", include_str!("../shaders/cell_projection/cap_pieces.frag")),
    ("cell_projection/radix_sort.glsl", include_str!("../shaders/cell_projection/radix_sort.glsl")),
    ("cell_projection/sort_keys.comp", include_str!("../shaders/cell_projection/sort_keys.comp")),
    ("cell_projection/sort_histogram.comp", include_str!("../shaders/cell_projection/sort_histogram.comp")),
    ("cell_projection/sort_scan.comp", include_str!("../shaders/cell_projection/sort_scan.comp")),
    ("cell_projection/sort_scatter.comp", include_str!("../shaders/cell_projection/sort_scatter.comp")),
    ("raycast/common.glsl", include_str!("../shaders/raycast/common.glsl")),
    ("raycast/box.vert", include_str!("../shaders/raycast/box.vert")),
    ("raycast/box.frag", include_str!("../shaders/raycast/box.frag")),
    ("raycast/fullscreen.vert", include_str!("../shaders/raycast/fullscreen.vert")),
    ("raycast/march.frag", include_str!("../shaders/raycast/march.frag")),
    ("raycast/march.comp", include_str!("../shaders/raycast/march.comp")),
    ("tet_raycast/walk.comp", include_str!("../shaders/tet_raycast/walk.comp")),
    ("terrain/common.glsl", include_str!("../shaders/terrain/common.glsl")),
    ("terrain/mesh.vert", include_str!("../shaders/terrain/mesh.vert")),
    ("terrain/mesh.frag", include_str!("../shaders/terrain/mesh.frag")),
    ("terrain/tessellate.glsl", include_str!("../shaders/terrain/tessellate.glsl")),
    ("terrain/pc.vert", include_str!("../shaders/terrain/pc.vert")),
    ("terrain/pc.geom", include_str!("../shaders/terrain/pc.geom")),
    ("terrain/pc.comp", include_str!("../shaders/terrain/pc.comp")),
];

/// The text of a shader or include, by its path under `shaders/`.
pub fn source(path: &str) -> Option<&'static str> {
    SOURCES.iter().find(|(p, _)| *p == path).map(|(_, s)| *s)
}

/// Every shader (not include) with its stage, for the compile-everything test.
pub fn all_entry_points() -> impl Iterator<Item = &'static str> {
    SOURCES.iter().map(|(p, _)| *p).filter(|p| !p.ends_with(".glsl"))
}

#[cfg(test)]
mod tests {
    use crate::vk::{compile_glsl, ShaderStage};

    #[test]
    fn every_shader_compiles() {
        for path in super::all_entry_points() {
            let stage = ShaderStage::from_path(path).unwrap_or_else(|| panic!("{path}: unknown shader stage"));
            compile_glsl(path, stage, &[], &super::source).unwrap_or_else(|e| panic!("{e}"));
        }
    }

    #[test]
    fn compile_errors_name_file_and_line() {
        let broken = |p: &str| match p {
            "broken.frag" => Some("#version 450\nvoid main() {\n  undefined_thing = 1;\n}\n"),
            _ => None,
        };
        let err = compile_glsl("broken.frag", ShaderStage::Fragment, &[], &broken).unwrap_err().to_string();
        assert!(err.contains("shaders/broken.frag:3"), "{err}");
    }
}
