//! The contract every rendering method meets, whatever data it renders.
//!
//! A method is described once, as data ([`MethodInfo`]): its name, the kind
//! of dataset it renders, its options (name, default, unit, allowed values,
//! and whether the option changes shader code or is a run-time parameter),
//! the device features it needs, the option sets sweeps should try, and a
//! constructor. What it builds is a [`RenderMethod`]: it owns its passes,
//! pipelines and per-frame data; the harness owns everything else (warm-up,
//! CPU/device overlap, timing, queries, readback, the result record). So a
//! new method is one module, its shaders and one line in `algo::registry`.

use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{bail, Result};
use serde::Serialize;

use crate::mesh::TetMesh;
use crate::scene::{Camera, TransferFunction};
use crate::vk::{CommandRecorder, Context, DeviceInfo, Image, UploadCounter};

/// What kind of dataset a method renders (`volbench list` groups by it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DataKind {
    /// An unstructured grid of tetrahedra with a scalar per point.
    TetMesh,
    /// A regular grid of scalars (CT, simulation output).
    Volume,
    /// A height field with embedded triangulated patches.
    Terrain,
}

impl DataKind {
    pub fn name(self) -> &'static str {
        match self {
            DataKind::TetMesh => "tet-mesh",
            DataKind::Volume => "volume",
            DataKind::Terrain => "terrain",
        }
    }

    /// The work count a run's rate is given in for this kind (a key of the
    /// result's `work.per_second`): a mesh's cells, the samples a volume's
    /// rays take, the triangles a terrain draws. Reports show the rate in
    /// this unit (`M cells/s`, `M samples/s`, `M triangles/s`), never
    /// another kind's.
    pub fn rate_unit(self) -> &'static str {
        match self {
            DataKind::TetMesh => "cells",
            DataKind::Volume => "samples",
            DataKind::Terrain => "triangles",
        }
    }
}

/// The values an option may take.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "kebab-case", tag = "type")]
pub enum OptionValues {
    /// One of these words.
    Choice { values: &'static [&'static str] },
    /// An integer in [min, max].
    Int { min: i64, max: i64 },
    /// A finite number in [min, max].
    Float { min: f64, max: f64 },
    /// on/off (also true/false, yes/no, 1/0).
    Bool,
}

/// One option of a method, described as data.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OptionSpec {
    pub name: &'static str,
    /// The default, in the same text form a spec gives it.
    pub default: &'static str,
    /// Unit of a number ("" for none).
    pub unit: &'static str,
    pub values: OptionValues,
    /// True when the option changes shader code (a define: a new pipeline),
    /// false for a run-time parameter (push constants, buffers).
    pub build_time: bool,
    pub help: &'static str,
}

/// One parsed option value.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum OptionValue {
    Text(String),
    Int(i64),
    Float(f64),
    Bool(bool),
}

impl std::fmt::Display for OptionValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OptionValue::Text(s) => f.write_str(s),
            OptionValue::Int(v) => write!(f, "{v}"),
            OptionValue::Float(v) => write!(f, "{v}"),
            OptionValue::Bool(v) => f.write_str(if *v { "on" } else { "off" }),
        }
    }
}

impl OptionSpec {
    /// Parse `text` as a value of this option; `method` names it in errors.
    pub fn parse(&self, method: &str, text: &str) -> Result<OptionValue> {
        let name = self.name;
        let text = text.trim();
        Ok(match self.values {
            OptionValues::Choice { values } => {
                if !values.contains(&text) {
                    bail!("method '{method}': option '{name}' must be one of {}, got '{text}'", values.join(", "));
                }
                OptionValue::Text(text.to_string())
            }
            OptionValues::Int { min, max } => {
                let v: i64 = text.parse().map_err(|_| {
                    anyhow::anyhow!("method '{method}': option '{name}' must be a whole number, got '{text}'")
                })?;
                if v < min || v > max {
                    bail!("method '{method}': option '{name}' = {v} is out of range [{min}, {max}]{}", unit_suffix(self.unit));
                }
                OptionValue::Int(v)
            }
            OptionValues::Float { min, max } => {
                let v: f64 = text
                    .parse()
                    .map_err(|_| anyhow::anyhow!("method '{method}': option '{name}' must be a number, got '{text}'"))?;
                if !v.is_finite() || v < min || v > max {
                    bail!("method '{method}': option '{name}' = {text} is out of range [{min}, {max}]{}", unit_suffix(self.unit));
                }
                OptionValue::Float(v)
            }
            OptionValues::Bool => match text.to_ascii_lowercase().as_str() {
                "on" | "true" | "yes" | "1" => OptionValue::Bool(true),
                "off" | "false" | "no" | "0" => OptionValue::Bool(false),
                _ => bail!("method '{method}': option '{name}' must be on or off, got '{text}'"),
            },
        })
    }

    /// The allowed values as text (for `volbench list`).
    pub fn allowed(&self) -> String {
        match self.values {
            OptionValues::Choice { values } => values.join("|"),
            OptionValues::Int { min, max } => format!("{min}..{max}"),
            OptionValues::Float { min, max } => format!("{min}..{max}"),
            OptionValues::Bool => "on|off".into(),
        }
    }
}

fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}

/// A method's complete, validated option set: every option it declares,
/// given or defaulted. Serialised as `options` in every result.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
#[serde(transparent)]
pub struct Options(pub BTreeMap<String, OptionValue>);

impl Options {
    /// The option's value as text (a choice, or a number as written).
    pub fn text(&self, name: &str) -> Result<String> {
        self.0.get(name).map(|v| v.to_string()).ok_or_else(|| anyhow::anyhow!("option '{name}' is not set"))
    }

    pub fn int(&self, name: &str) -> Result<i64> {
        match self.0.get(name) {
            Some(OptionValue::Int(v)) => Ok(*v),
            _ => bail!("option '{name}' is not a whole number"),
        }
    }

    pub fn float(&self, name: &str) -> Result<f64> {
        match self.0.get(name) {
            Some(OptionValue::Float(v)) => Ok(*v),
            Some(OptionValue::Int(v)) => Ok(*v as f64),
            _ => bail!("option '{name}' is not a number"),
        }
    }

    pub fn flag(&self, name: &str) -> Result<bool> {
        match self.0.get(name) {
            Some(OptionValue::Bool(v)) => Ok(*v),
            _ => bail!("option '{name}' is not on/off"),
        }
    }

    /// `key=value,...` in name order (how a spec writes them).
    pub fn to_spec_string(&self) -> String {
        self.0.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(",")
    }
}

/// A device capability a method may need.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Feature {
    GeometryShader,
    PipelineStatistics,
    /// Storage-buffer writes and atomics in the fragment stage.
    FragmentStoresAndAtomics,
    /// Primitives not clipped at the near and far planes, and a user clip
    /// plane just in front of the eye instead (cell projection: a cell cut
    /// by the near plane is integrated from it).
    DepthClamp,
}

impl Feature {
    /// Whether the device has it; `Err` says why not.
    pub fn check(self, info: &DeviceInfo) -> Result<(), String> {
        let ok = match self {
            Feature::GeometryShader => info.features.geometry_shader,
            Feature::PipelineStatistics => info.features.pipeline_statistics_query,
            Feature::FragmentStoresAndAtomics => info.features.fragment_stores_and_atomics,
            Feature::DepthClamp => info.features.depth_clamp && info.features.shader_clip_distance,
        };
        if ok {
            Ok(())
        } else {
            Err(format!("device '{}' lacks {}", info.name, self.name()))
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Feature::GeometryShader => "the geometry-shader stage (geometryShader)",
            Feature::PipelineStatistics => "pipeline-statistics queries (pipelineStatisticsQuery)",
            Feature::FragmentStoresAndAtomics => "fragment-stage storage writes and atomics (fragmentStoresAndAtomics)",
            Feature::DepthClamp => "primitives unclipped at the near and far planes (depthClamp, shaderClipDistance)",
        }
    }
}

/// The dataset a method renders, by kind.
#[derive(Clone, Copy)]
pub enum SceneData<'a> {
    TetMesh { mesh: &'a TetMesh },
    Volume(&'a crate::volume::Volume),
    Terrain(&'a crate::terrain::Heightmap),
}

impl SceneData<'_> {
    pub fn kind(&self) -> DataKind {
        match self {
            SceneData::TetMesh { .. } => DataKind::TetMesh,
            SceneData::Volume(_) => DataKind::Volume,
            SceneData::Terrain(_) => DataKind::Terrain,
        }
    }
}

/// Everything a method's constructor gets.
pub struct MethodInputs<'a> {
    pub ctx: &'a Arc<Context>,
    pub data: SceneData<'a>,
    pub tf: &'a TransferFunction,
    pub options: &'a Options,
    pub width: u32,
    pub height: u32,
    /// The run will ask for `RenderMethod::diagnostics` (build what it needs).
    pub diagnostics: bool,
    /// One-time uploads made while building (static bytes).
    pub counter: &'a mut UploadCounter,
    /// A volume's samples, taken from `data`'s volume
    /// (`Volume::take_samples`) when nothing reads them after the set-up
    /// (a single run): the method gives them back as they reach the device,
    /// so the samples are held once, not twice. `None`: `data` holds them.
    pub samples: Option<crate::volume::Samples>,
}

/// One frame's view: the camera and the image it is drawn into.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
}

/// The end of the name of every device phase (`RenderMethod::after_frame`):
/// reports keep them apart from the CPU's preparation.
pub const DEVICE_PHASE_SUFFIX: &str = "_gpu";

/// What a method measured of one frame: named phases, in milliseconds
/// (CPU: e.g. `sort`, `pack`; device passes a method times itself, named
/// with [`DEVICE_PHASE_SUFFIX`]: e.g. `sort_gpu`), reported as
/// `time_ms.<name>` beside the runner's own phases; named per-frame counts
/// (e.g. `cull.frustum`, cells skipped by a rule), reported as
/// `frame_counts.<name>` per timed frame; and the frame's own error, for a
/// method that measures it itself ([`Phases::own_error`]).
#[derive(Debug, Clone, Default)]
pub struct Phases(pub Vec<(&'static str, f64)>, pub Vec<(&'static str, u64)>, pub Option<OwnError>);

impl Phases {
    pub fn add(&mut self, name: &'static str, ms: f64) {
        self.0.push((name, ms));
    }

    /// A CPU phase that ends now and took `ms`: recorded as `add` does, and
    /// under `volbench run --count` the instructions since the previous
    /// phase boundary are counted as `name` (`vk::valgrind::mark`).
    pub fn ended(&mut self, name: &'static str, ms: f64) {
        crate::vk::valgrind::mark(name);
        self.add(name, ms);
    }

    pub fn count(&mut self, name: &'static str, n: u64) {
        self.1.push((name, n));
    }

    /// The frame's error measured by the method itself against the
    /// full-resolution data, for datasets without an image reference (a
    /// terrain's level of detail: height error). The runner records the
    /// reference view's as the result's `error`, and sweeps plot it.
    pub fn own_error(&mut self, e: OwnError) {
        self.2 = Some(e);
    }
}

/// What a method processes per frame, by unit (`cells`, `pixels`,
/// `triangles`, ...): deterministic counts, reported as `work` with a
/// per-second rate. `vertices_per_cell` and the like go in `details`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Work(pub BTreeMap<&'static str, u64>);

impl Work {
    pub fn with(mut self, unit: &'static str, count: u64) -> Self {
        self.0.insert(unit, count);
        self
    }
}

/// A method built for one dataset, transfer function, option set and size:
/// what every method does. What only a family does lives with the family
/// (`Family`: its camera path, checks, bound, suite roles) or in what a
/// frame reports (`Phases`: phases, counts, an own error measure).
pub trait RenderMethod {
    /// The CPU half of a frame (sort, pack, level-of-detail, ...). It may run
    /// while the device still draws the previous frame: it must write host
    /// memory the device does not read until `upload`.
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()>;
    /// Move this frame's data to where the device reads it (counted).
    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()>;
    /// Record the frame's passes; the final image ends in `target`
    /// (RGBA32F, premultiplied colour and alpha). Push constants are counted.
    fn record(&mut self, rec: &CommandRecorder, target: &Image, view: &View, counter: &mut UploadCounter) -> Result<()>;
    /// What one frame processes (deterministic).
    fn work(&self) -> Work;
    /// Family-specific facts for the result's `details` section (table sizes,
    /// tolerances, vertices per cell, ...).
    fn details(&self) -> serde_json::Value;
    /// Extra checks of the reference view that may be costly (e.g. how far
    /// a sort is from a visibility order); the runner asks when told to.
    fn diagnostics(&mut self, _view: &View) -> Result<Option<serde_json::Value>> {
        Ok(None)
    }
    /// After the frame's fence: add phases the device measured for it (GPU
    /// times of the method's own passes, from its timestamps, named
    /// `<pass>_gpu`) to `phases`.
    fn after_frame(&mut self, _phases: &mut Phases) -> Result<()> {
        Ok(())
    }
    /// CPU time spent building tables at set-up (ms), reported apart.
    fn table_build_ms(&self) -> f64 {
        0.0
    }
}

/// See `Phases::own_error`.
#[derive(Debug, Clone, PartialEq)]
pub struct OwnError {
    pub rmse: f64,
    pub max_abs: f64,
    /// What was compared, with the unit.
    pub what: &'static str,
}

/// A figure the literature published for a method, set beside the measured
/// one in reports. Absolute numbers come from other hardware: reports read
/// them only as ratios between runs on one dataset. The suite runs every
/// option set a published figure names, so each figure has its measured
/// counterpart.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Published {
    pub method: &'static str,
    /// The dataset the paper measured (`None`: its own data, a claim about
    /// the method on any dataset of its kind).
    pub dataset: Option<&'static str>,
    /// The option set the figure is for (`""`: the defaults).
    pub options: &'static str,
    pub figure: PublishedFigure,
    pub source: &'static str,
    /// What makes the measured ratio differ from the published one on other
    /// hardware (the report prints it under the table).
    pub note: &'static str,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PublishedFigure {
    /// Frames per second on the paper's machine, with the cells per frame
    /// it rendered (cells per second = fps × cells).
    Fps { fps: f64, cells: u64 },
    /// The defaults run up to this many times faster than this option set.
    DefaultsFasterUpTo(f64),
    /// Cells drawn per frame for a mesh of `cells` cells (a method that
    /// draws a cell more than once; set beside the run's `work.pieces`).
    CellsRendered { rendered: u64, cells: u64 },
}

impl Published {
    /// Frames per second, when the figure is one.
    pub fn fps(&self) -> Option<f64> {
        match self.figure {
            PublishedFigure::Fps { fps, .. } => Some(fps),
            PublishedFigure::DefaultsFasterUpTo(_) | PublishedFigure::CellsRendered { .. } => None,
        }
    }

    /// Cells per second, when the figure is a frame rate.
    pub fn cells_per_second(&self) -> Option<f64> {
        match self.figure {
            PublishedFigure::Fps { fps, cells } => Some(fps * cells as f64),
            PublishedFigure::DefaultsFasterUpTo(_) | PublishedFigure::CellsRendered { .. } => None,
        }
    }

    /// Whether the figure speaks about `dataset`.
    pub fn applies_to(&self, dataset: &str) -> bool {
        self.dataset.is_none_or(|d| d == dataset)
    }
}

/// A method's registration (see the module note).
#[derive(Clone)]
pub struct MethodInfo {
    pub name: &'static str,
    pub data: DataKind,
    pub summary: &'static str,
    pub options: &'static [OptionSpec],
    pub features: &'static [Feature],
    /// Option sets (`key=value,...`) a run-time-against-error sweep tries.
    pub sweep: &'static [&'static str],
    /// Option sets `compare` shows side by side ("" = the defaults).
    pub compare: &'static [&'static str],
    /// Option sets the stress suite renders every case of its kind with.
    pub stress: &'static [&'static str],
    /// Option sets the benchmark suite runs besides the defaults and the
    /// published figures' sets: the cheaper end of the method's accuracy
    /// trade-off, so a report can set it beside a peer at matched error, or
    /// its exact end, so other methods' errors can be set beside it.
    pub suite: &'static [&'static str],
    /// Published figures for this method (reports).
    pub published: &'static [Published],
    /// What the method's family registers once (checks, bounds, its roles
    /// in the suite).
    pub family: Family,
    pub create: fn(MethodInputs) -> Result<Box<dyn RenderMethod>>,
}

/// What a family of methods registers once for all its members, so that
/// the harness names none of their options or detail keys.
#[derive(Debug, Clone, Copy)]
pub struct Family {
    pub name: &'static str,
    /// Checks a complete option set beyond each option's own range (e.g. a
    /// table size against the memory its integrator's table implies), so
    /// that every spec is refused when parsed, before any Vulkan work
    /// (`settings::check` of the family's settings type).
    pub check: fn(&Options) -> Result<()>,
    /// The max |error| against the f64 reference the stress suite holds a
    /// render with these options to where a case documents no limitation
    /// (`perspective`: the case's view is); `None` when for such a view the
    /// option set computes the same as another of its stress sets (rendered
    /// once), or when the family has no image reference.
    pub accuracy_bound: fn(&Options, bool) -> Option<f64>,
    /// An on/off option that leaves the image unchanged and saves work: the
    /// suite's culling scenes run the first methods that have it both ways,
    /// compare the images and report the saving.
    pub culling_option: Option<&'static str>,
    /// The work the family's methods share, each placed differently (e.g.
    /// where the terrain's PC cells are tessellated): the report sets their
    /// runs on one dataset side by side.
    pub placement: Option<&'static str>,
    /// The camera of frame `frame` when the family flies its own path over
    /// its data (a terrain fly-over); `None` keeps the runner's orbit. A
    /// run's fixed camera wins over both.
    pub camera: fn(&SceneData, usize) -> Option<Camera>,
}

impl Family {
    /// A family with independent options, no error bound and no role in
    /// the suite beyond its runs.
    pub const fn plain(name: &'static str) -> Self {
        Family { name, check: |_| Ok(()), accuracy_bound: |_, _| None, culling_option: None, placement: None, camera: |_, _| None }
    }
}

impl std::fmt::Debug for MethodInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MethodInfo").field("name", &self.name).field("data", &self.data).finish_non_exhaustive()
    }
}

impl MethodInfo {
    pub fn option(&self, name: &str) -> Option<&'static OptionSpec> {
        self.options.iter().find(|o| o.name == name)
    }

    /// Every option at its default, then `given` (`(name, value)` pairs)
    /// applied in order; unknown options and bad values are errors naming
    /// the option and this method.
    pub fn options_from<'a>(&self, given: impl IntoIterator<Item = (&'a str, &'a str)>) -> Result<Options> {
        let mut out = BTreeMap::new();
        for o in self.options {
            out.insert(o.name.to_string(), o.parse(self.name, o.default)?);
        }
        for (k, v) in given {
            let Some(spec) = self.option(k) else {
                let known: Vec<&str> = self.options.iter().map(|o| o.name).collect();
                bail!(
                    "method '{}' has no option '{k}' (its options: {})",
                    self.name,
                    if known.is_empty() { "none".to_string() } else { known.join(", ") }
                );
            };
            out.insert(k.to_string(), spec.parse(self.name, v)?);
        }
        let options = Options(out);
        (self.family.check)(&options).map_err(|e| anyhow::anyhow!("method '{}': {e:#}", self.name))?;
        Ok(options)
    }

    /// The family's culling option, when this method has it.
    pub fn culling_option(&self) -> Option<&'static str> {
        self.family.culling_option.filter(|o| self.option(o).is_some())
    }

    /// Why this device cannot run the method, if it cannot.
    pub fn unsupported_reason(&self, info: &DeviceInfo) -> Option<String> {
        self.features.iter().find_map(|f| f.check(info).err())
    }
}

/// Parse `key=value,key=value` (empty: none) into pairs; a pair without `=`
/// is an error naming it.
pub fn parse_pairs(text: &str) -> Result<Vec<(&str, &str)>> {
    let pairs: Vec<(&str, &str)> = text
        .split(',')
        .map(str::trim)
        .filter(|p| !p.is_empty())
        .map(|p| {
            p.split_once('=')
                .map(|(k, v)| (k.trim(), v.trim()))
                .filter(|(k, _)| !k.is_empty())
                .ok_or_else(|| anyhow::anyhow!("'{p}' is not key=value"))
        })
        .collect::<Result<_>>()?;
    // A key given twice in one spec is a typo, not an override.
    for (i, (k, _)) in pairs.iter().enumerate() {
        if pairs[..i].iter().any(|(j, _)| j == k) {
            bail!("option '{k}' is given twice");
        }
    }
    Ok(pairs)
}
