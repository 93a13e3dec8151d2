//! GLSL -> SPIR-V with shaderc at run time, for every stage we use (vertex,
//! geometry, fragment, compute). Sources come from a lookup the caller
//! provides (volbench embeds `shaders/` in the binary; tests may pass inline
//! text), so `#include` works the same in tests and installed binaries.
//! Compile errors keep shaderc's `file:line: error:` form, which names the
//! file and line.

use std::sync::Arc;

use ash::vk;

use super::error::{Check, VkError, VkResult};
use super::Context;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ShaderStage {
    Vertex,
    Fragment,
    Geometry,
    Compute,
}

impl ShaderStage {
    /// The stage a file name says (`.vert`, `.geom`, `.frag`, `.comp`).
    pub fn from_path(path: &str) -> Option<ShaderStage> {
        match path.rsplit_once('.')?.1 {
            "vert" => Some(ShaderStage::Vertex),
            "geom" => Some(ShaderStage::Geometry),
            "frag" => Some(ShaderStage::Fragment),
            "comp" => Some(ShaderStage::Compute),
            _ => None,
        }
    }

    /// A stable small code for canonical serialisation (pipeline-key ids).
    pub(crate) fn code(self) -> u8 {
        match self {
            ShaderStage::Vertex => 0,
            ShaderStage::Fragment => 1,
            ShaderStage::Geometry => 2,
            ShaderStage::Compute => 3,
        }
    }

    fn kind(self) -> shaderc::ShaderKind {
        match self {
            ShaderStage::Vertex => shaderc::ShaderKind::Vertex,
            ShaderStage::Fragment => shaderc::ShaderKind::Fragment,
            ShaderStage::Geometry => shaderc::ShaderKind::Geometry,
            ShaderStage::Compute => shaderc::ShaderKind::Compute,
        }
    }
}

/// Compile `path` (a name the lookup knows, e.g. `cell_projection/vicp.vert`)
/// with `defines`. `lookup` returns the text of any shader or include by path.
pub fn compile_glsl(
    path: &str,
    stage: ShaderStage,
    defines: &[(&str, &str)],
    lookup: &dyn Fn(&str) -> Option<&'static str>,
) -> VkResult<Vec<u32>> {
    let source = lookup(path).ok_or_else(|| VkError::Shader(format!("shaders/{path}: no such shader")))?;
    let compiler = shaderc::Compiler::new().map_err(|e| VkError::Shader(format!("shaderc unavailable: {e}")))?;
    let mut options =
        shaderc::CompileOptions::new().map_err(|e| VkError::Shader(format!("shaderc options: {e}")))?;
    options.set_target_env(shaderc::TargetEnv::Vulkan, shaderc::EnvVersion::Vulkan1_3 as u32);
    options.set_optimization_level(shaderc::OptimizationLevel::Performance);
    options.set_warnings_as_errors();
    for (k, v) in defines {
        options.add_macro_definition(k, Some(v));
    }
    options.set_include_callback(move |requested, _kind, requester, _depth| {
        // Includes are resolved relative to shaders/ (like "common/x.glsl").
        let _ = requester;
        match lookup(requested) {
            Some(text) => Ok(shaderc::ResolvedInclude {
                resolved_name: format!("shaders/{requested}"),
                content: text.to_string(),
            }),
            None => Err(format!("shaders/{requested}: include not found")),
        }
    });
    let display = format!("shaders/{path}");
    let artifact = compiler
        .compile_into_spirv(source, stage.kind(), &display, "main", Some(&options))
        .map_err(|e| VkError::Shader(format!("compiling {display}: {e}")))?;
    Ok(artifact.as_binary().to_vec())
}

/// A `vk::ShaderModule` destroyed on drop.
pub struct ShaderModule {
    pub raw: vk::ShaderModule,
    pub stage: ShaderStage,
    ctx: Arc<Context>,
}

impl ShaderModule {
    pub fn new(ctx: &Arc<Context>, name: &str, stage: ShaderStage, spirv: &[u32]) -> VkResult<Self> {
        let info = vk::ShaderModuleCreateInfo::default().code(spirv);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_shader_module(&info, None) }.check("vkCreateShaderModule")?;
        ctx.set_name(raw, name);
        Ok(ShaderModule { raw, stage, ctx: ctx.clone() })
    }
}

impl Drop for ShaderModule {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_shader_module(self.raw, None) };
    }
}
