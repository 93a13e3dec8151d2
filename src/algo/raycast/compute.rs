//! `raycast-compute`: the whole integral in one compute pass (analytic
//! ray–box clipping, no entry/exit targets), writing the runner's target as
//! a storage image. Same march as `raycast-fragment` (see `super`).

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use crate::algo::screen;
use crate::algo::settings::MethodSettings;
use super::{BoxOnScreen, Settings, VolumeResources, COMPARE, OPTIONS, PUSH_BYTES, STRESS, SUITE, SWEEP};
use crate::algo::method::{DataKind, MethodInfo, MethodInputs, Phases, RenderMethod, SceneData, View, Work};
use crate::vk::{
    CommandRecorder, ComputePipelineKey, Image, Pipeline, PipelineKey, ShaderKey, ShaderStage, TargetImageSet,
    UploadCounter,
};
use crate::vk::Stages;

/// Workgroup shape (pixels).
pub const WORKGROUP: [u32; 2] = [8, 8];

pub const METHOD: MethodInfo = MethodInfo {
    name: "raycast-compute",
    data: DataKind::Volume,
    summary: "GPU ray casting in one compute pass: analytic ray-box clipping, trilinear samples, 1D TF, front to back",
    options: OPTIONS,
    features: &[],
    sweep: SWEEP,
    compare: COMPARE,
    stress: STRESS,
    suite: SUITE,
    published: &[super::kruger_westermann("raycast-compute")],
    family: super::FAMILY,
    create,
};

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Volume(vol) = inputs.data else { bail!("raycast-compute renders volumes only") };
    let settings = Settings::from_options(inputs.options)?;
    let res = VolumeResources::new(inputs.ctx, vol, inputs.samples, inputs.tf, &settings, inputs.counter)?;
    let defines = res.defines(&settings);
    let wg = [WORKGROUP[0].to_string(), WORKGROUP[1].to_string()];
    let mut all: Vec<(&str, &str)> = defines.clone();
    // The march's counters reduced per subgroup (common.glsl) where the
    // device can.
    if inputs.ctx.info.compute_subgroup_arithmetic {
        all.push(("SUBGROUP_COUNTERS", "1"));
    }
    all.push(("WG_X", &wg[0]));
    all.push(("WG_Y", &wg[1]));
    let target_set = TargetImageSet::new("raycast target", Stages::COMPUTE);
    let key = PipelineKey::Compute(ComputePipelineKey {
        shader: ShaderKey::new("raycast/march.comp", ShaderStage::Compute, &all),
        push_constant_bytes: PUSH_BYTES,
        sets: vec![res.set0_desc(), target_set.desc.clone()],
    });
    let pipeline = crate::algo::pipelines::get(inputs.ctx, &key)?;
    Ok(Box::new(RaycastCompute {
        res,
        settings,
        pipeline,
        key,
        target_set,
        push: Vec::new(),
        groups: [0, 0, 1],
        whole_image: false,
        pixels: inputs.width as u64 * inputs.height as u64,
        ctx: inputs.ctx.clone(),
    }))
}

pub struct RaycastCompute {
    res: VolumeResources,
    settings: Settings,
    pipeline: Arc<Pipeline>,
    key: PipelineKey,
    /// Set 1: the target as a storage image.
    target_set: TargetImageSet,
    push: Vec<u8>,
    /// Workgroups dispatched (over the box's tiles), and whether they cover
    /// the whole image.
    groups: [u32; 3],
    whole_image: bool,
    pixels: u64,
    ctx: Arc<crate::vk::Context>,
}

impl RenderMethod for RaycastCompute {
    fn prepare(&mut self, view: &View, _phases: &mut Phases) -> Result<()> {
        let all = [view.width.div_ceil(WORKGROUP[0]), view.height.div_ceil(WORKGROUP[1])];
        // Only the tiles over the box's pixels (its place in the view).
        let (base, groups) = match self.res.on_screen(view) {
            BoxOnScreen::Hidden => ([0; 3], [0, 0, 1]),
            BoxOnScreen::Whole { rect } => screen::groups_over(rect, WORKGROUP),
            BoxOnScreen::Cut => ([0; 3], [all[0], all[1], 1]),
        };
        // Rows interleaved over the device's runs of workgroups
        // (algo::screen::interleaved_rows).
        let runs = self.ctx.info.compute_runs();
        self.groups = [groups[0], screen::interleaved_rows(groups[1], runs), 1];
        self.whole_image = groups[..2] == all;
        self.push = self.res.push_constants(view, true, [base[0], base[1], groups[1], runs]);
        Ok(())
    }

    fn upload(&mut self, _counter: &mut UploadCounter) -> Result<()> {
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, _view: &View, counter: &mut UploadCounter) -> Result<()> {
        let set = self.target_set.for_target(&self.ctx, target)?;
        self.res.record_clear(rec);
        // Only the tiles over the box's pixels run the march (on llvmpipe an
        // invocation whose ray misses still runs the whole shader masked:
        // crate::algo::screen); the rest of the target is cleared.
        rec.storage_target(target, self.whole_image);
        if self.groups[0] > 0 && self.groups[1] > 0 {
            rec.bind_compute(&self.pipeline, &[&self.res.set, set])?;
            rec.push_constants(&self.pipeline, &self.push, counter);
            rec.dispatch(self.groups)?;
        }
        self.res.record_counters_to_host(rec);
        Ok(())
    }

    fn work(&self) -> Work {
        self.res.work(self.pixels)
    }

    fn details(&self) -> serde_json::Value {
        self.res.details(
            &self.settings,
            json!({
                "name": "compute",
                "workgroup": WORKGROUP,
                "counter_atomics": if self.ctx.info.compute_subgroup_arithmetic { "per subgroup" } else { "per ray" },
                "pipeline": { "key": self.key.id(), "name": self.key.name() },
            }),
        )
    }

    fn table_build_ms(&self) -> f64 {
        self.res.table_build_ms
    }
}
