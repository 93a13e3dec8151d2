//! Pipelines cached by what they are built from. A `PipelineKey` is the
//! owned, `Hash + Eq` description of a pipeline: shader paths (under
//! `shaders/`) with their stage and defines, the fixed-function state, the
//! colour formats and blends, push-constant size and descriptor-set layouts.
//! Equal keys give the same `Arc<Pipeline>`; any build-time option (a define,
//! a blend, a format) changes the key and builds a new pipeline.
//!
//! `PipelineKey::id` is a short, stable name for results: 16 hex digits of
//! FNV-1a (64 bit) over a canonical serialisation of the key (explicit
//! field order, raw Vulkan enum values, length-prefixed strings, defines
//! sorted by name). Unlike `std`'s `DefaultHasher` it does not change between
//! Rust versions, platforms or runs. It covers the key, not the shader text:
//! results record the git commit for that.
//!
//! The cache also holds a `VkPipelineCache`, so the driver can reuse
//! compiled code between pipelines that share shaders.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::sync::{Arc, Mutex};

use ash::vk;

use super::descriptors::{check_stage_limits, DescriptorSetDesc, DescriptorSetLayout};
use super::error::{Check, VkResult};
use super::pipeline::{ColorTarget, ComputePipelineDesc, GraphicsPipelineDesc, Pipeline, VertexAttribute};
use super::shader::{compile_glsl, ShaderModule, ShaderStage};
use super::types::{Cull, Topology, Winding};
use super::Context;

/// One shader: its path under `shaders/`, stage and preprocessor defines.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ShaderKey {
    pub path: String,
    pub stage: ShaderStage,
    /// Name -> value; a name given twice keeps its last value.
    pub defines: BTreeMap<String, String>,
}

impl ShaderKey {
    pub fn new(path: &str, stage: ShaderStage, defines: &[(&str, &str)]) -> Self {
        ShaderKey {
            path: path.to_string(),
            stage,
            defines: defines.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
        }
    }

    fn compile(&self, lookup: &dyn Fn(&str) -> Option<&'static str>) -> VkResult<Vec<u32>> {
        let defines: Vec<(&str, &str)> = self.defines.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        compile_glsl(&self.path, self.stage, &defines, lookup)
    }

    fn write_canonical(&self, out: &mut String) {
        out.push_str("shader(");
        put_str(out, &self.path);
        let _ = write!(out, "{},", self.stage.code());
        for (k, v) in &self.defines {
            put_str(out, k);
            put_str(out, v);
        }
        out.push(')');
    }
}

/// Fixed-function state of a graphics pipeline.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct GraphicsState {
    pub vertex_stride: u32,
    pub attributes: Vec<VertexAttribute>,
    pub topology: Topology,
    pub primitive_restart: bool,
    pub cull: Cull,
    pub front_face: Winding,
    pub targets: Vec<ColorTarget>,
    /// Depth test and write (`GraphicsPipelineDesc::depth_test`).
    pub depth_test: bool,
    /// No near/far clipping (`GraphicsPipelineDesc::depth_clamp`).
    pub depth_clamp: bool,
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct GraphicsPipelineKey {
    pub vertex: ShaderKey,
    pub geometry: Option<ShaderKey>,
    pub fragment: ShaderKey,
    pub state: GraphicsState,
    pub push_constant_bytes: u32,
    pub sets: Vec<DescriptorSetDesc>,
}

#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ComputePipelineKey {
    pub shader: ShaderKey,
    pub push_constant_bytes: u32,
    pub sets: Vec<DescriptorSetDesc>,
}

/// Everything a pipeline is built from.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum PipelineKey {
    Graphics(GraphicsPipelineKey),
    Compute(ComputePipelineKey),
}

/// FNV-1a, 64 bit.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn put_str(out: &mut String, s: &str) {
    let _ = write!(out, "{}:{s},", s.len());
}

fn put_sets(out: &mut String, sets: &[DescriptorSetDesc]) {
    out.push_str("sets[");
    for s in sets {
        out.push('[');
        for b in &s.bindings {
            let _ = write!(out, "{}/{},", b.kind.code(), b.stages.to_vk().as_raw());
        }
        out.push(']');
    }
    out.push(']');
}

impl PipelineKey {
    /// The canonical serialisation the id hashes (version-tagged, so a
    /// format change changes every id instead of colliding).
    pub fn canonical(&self) -> String {
        let mut out = String::from("volbench-pipeline-v1;");
        match self {
            PipelineKey::Graphics(g) => {
                out.push_str("graphics;");
                g.vertex.write_canonical(&mut out);
                match &g.geometry {
                    Some(s) => s.write_canonical(&mut out),
                    None => out.push_str("no-geometry"),
                }
                g.fragment.write_canonical(&mut out);
                let s = &g.state;
                let _ = write!(
                    out,
                    ";stride={};topology={};restart={};cull={};front={};attrs[",
                    s.vertex_stride,
                    s.topology.to_vk().as_raw(),
                    s.primitive_restart as u8,
                    s.cull.to_vk().as_raw(),
                    s.front_face.to_vk().as_raw()
                );
                for a in &s.attributes {
                    let _ = write!(out, "{}/{}/{},", a.location, a.format.to_vk().as_raw(), a.offset);
                }
                out.push_str("];targets[");
                for t in &s.targets {
                    let _ = write!(out, "{}/{},", t.format.to_vk().as_raw(), t.blend.code());
                }
                // Written only when on, so keys without depth keep their ids.
                let depth = if s.depth_test { ";depth=1" } else { "" };
                let clamp = if s.depth_clamp { ";clamp=1" } else { "" };
                let _ = write!(out, "]{depth}{clamp};push={};", g.push_constant_bytes);
                put_sets(&mut out, &g.sets);
            }
            PipelineKey::Compute(c) => {
                out.push_str("compute;");
                c.shader.write_canonical(&mut out);
                let _ = write!(out, ";push={};", c.push_constant_bytes);
                put_sets(&mut out, &c.sets);
            }
        }
        out
    }

    /// 16 lower-case hex digits identifying the key (see the module notes).
    pub fn id(&self) -> String {
        format!("{:016x}", fnv1a64(self.canonical().as_bytes()))
    }

    /// A readable name (shader paths) for debug names and messages.
    pub fn name(&self) -> String {
        match self {
            PipelineKey::Graphics(g) => {
                let mut n = format!("{} + ", g.vertex.path);
                if let Some(s) = &g.geometry {
                    n.push_str(&s.path);
                    n.push_str(" + ");
                }
                n.push_str(&g.fragment.path);
                n
            }
            PipelineKey::Compute(c) => c.shader.path.clone(),
        }
    }
}

type Lookup = dyn Fn(&str) -> Option<&'static str> + Send + Sync;

/// Pipelines by key, built on first request with a shared VkPipelineCache.
pub struct PipelineCache {
    pub raw: vk::PipelineCache,
    lookup: Box<Lookup>,
    pipelines: Mutex<HashMap<PipelineKey, Arc<Pipeline>>>,
    ctx: Arc<Context>,
}

impl PipelineCache {
    /// `lookup` resolves shader and include paths (volbench passes
    /// `crate::shaders::source`).
    pub fn new(ctx: &Arc<Context>, lookup: impl Fn(&str) -> Option<&'static str> + Send + Sync + 'static) -> VkResult<Self> {
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None) }
            .check("vkCreatePipelineCache")?;
        ctx.set_name(raw, "volbench pipeline cache");
        Ok(PipelineCache { raw, lookup: Box::new(lookup), pipelines: Mutex::new(HashMap::new()), ctx: ctx.clone() })
    }

    /// The pipeline for `key`, built (shaders compiled, layouts made) the
    /// first time and shared afterwards.
    pub fn get(&self, key: &PipelineKey) -> VkResult<Arc<Pipeline>> {
        let mut map = self.pipelines.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(p) = map.get(key) {
            return Ok(p.clone());
        }
        let pipeline = Arc::new(self.build(key)?);
        map.insert(key.clone(), pipeline.clone());
        Ok(pipeline)
    }

    /// Number of distinct pipelines built so far.
    pub fn len(&self) -> usize {
        self.pipelines.lock().map(|m| m.len()).unwrap_or(0)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn build(&self, key: &PipelineKey) -> VkResult<Pipeline> {
        let ctx = &self.ctx;
        let name = key.name();
        let module = |s: &ShaderKey| -> VkResult<ShaderModule> {
            let spirv = s.compile(&*self.lookup)?;
            ShaderModule::new(ctx, &s.path, s.stage, &spirv)
        };
        let layouts = |sets: &[DescriptorSetDesc]| -> VkResult<Vec<DescriptorSetLayout>> {
            check_stage_limits(&ctx.info, &name, sets)?;
            sets.iter().map(|s| DescriptorSetLayout::new(ctx, s)).collect()
        };
        match key {
            PipelineKey::Graphics(g) => {
                let vs = module(&g.vertex)?;
                let gs = g.geometry.as_ref().map(module).transpose()?;
                let fs = module(&g.fragment)?;
                let owned = layouts(&g.sets)?;
                let raw_layouts: Vec<vk::DescriptorSetLayout> = owned.iter().map(|l| l.raw).collect();
                let s = &g.state;
                let desc = GraphicsPipelineDesc {
                    name: &name,
                    vertex: &vs,
                    geometry: gs.as_ref(),
                    fragment: &fs,
                    vertex_stride: s.vertex_stride,
                    attributes: &s.attributes,
                    topology: s.topology,
                    primitive_restart: s.primitive_restart,
                    cull: s.cull,
                    front_face: s.front_face,
                    targets: &s.targets,
                    depth_test: s.depth_test,
                    depth_clamp: s.depth_clamp,
                    push_constant_bytes: g.push_constant_bytes,
                    descriptor_layouts: &raw_layouts,
                };
                Pipeline::graphics_in(ctx, &desc, self.raw, owned)
            }
            PipelineKey::Compute(c) => {
                let cs = module(&c.shader)?;
                let owned = layouts(&c.sets)?;
                let raw_layouts: Vec<vk::DescriptorSetLayout> = owned.iter().map(|l| l.raw).collect();
                let desc = ComputePipelineDesc {
                    name: &name,
                    shader: &cs,
                    push_constant_bytes: c.push_constant_bytes,
                    descriptor_layouts: &raw_layouts,
                };
                Pipeline::compute_in(ctx, &desc, self.raw, owned)
            }
        }
    }
}

impl Drop for PipelineCache {
    fn drop(&mut self) {
        // Pipelines still shared elsewhere stay valid: they do not depend on
        // the VkPipelineCache they were created with.
        if let Ok(mut m) = self.pipelines.lock() {
            m.clear();
        }
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_pipeline_cache(self.raw, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a64_matches_the_reference_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x85944171f73967e8);
    }
}
