//! `raycast-compute`: the whole integral in one compute pass (analytic
//! ray–box clipping, no entry/exit targets), writing the runner's target as
//! a storage image. Same march as `raycast-fragment` (see `super`).

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use crate::algo::screen;
use crate::algo::settings::MethodSettings;
use super::{AdaptiveFrame, BoxOnScreen, Frame, Settings, VolumeResources, COMPARE, OPTIONS, STRESS_COMPUTE, SUITE_COMPUTE, SWEEP_COMPUTE};
use crate::algo::adaptive::Adaptive;
use crate::algo::method::{DataKind, MethodInfo, MethodInputs, Phases, RenderMethod, SceneData, View, Work};
use crate::vk::{CommandRecorder, Image, Pipeline, PipelineKey, TargetImageSet, UploadCounter};
use crate::vk::Stages;

/// Workgroup shape (pixels).
pub const WORKGROUP: [u32; 2] = super::COMPUTE_WORKGROUP;

pub const METHOD: MethodInfo = MethodInfo {
    name: "raycast-compute",
    data: DataKind::Volume,
    summary: "GPU ray casting in one compute pass: analytic ray-box clipping, trilinear samples, 1D TF, front to back",
    options: OPTIONS,
    features: &[],
    sweep: SWEEP_COMPUTE,
    compare: COMPARE,
    stress: STRESS_COMPUTE,
    suite: SUITE_COMPUTE,
    published: &[super::kruger_westermann("raycast-compute")],
    family: super::FAMILY,
    create,
};

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Volume(vol) = inputs.data else { bail!("raycast-compute renders volumes only") };
    let settings = Settings::from_options(inputs.options)?;
    let res = VolumeResources::new(inputs.ctx, vol, inputs.samples, inputs.tf, &settings, inputs.counter)?;
    let facts = res.shader_facts(inputs.ctx);
    let target_set = TargetImageSet::new("raycast target", Stages::COMPUTE);
    let key = settings.compute_key(facts, &target_set.desc, None);
    let pipeline = crate::algo::pipelines::get(inputs.ctx, &key)?;
    // Adaptive refinement: the march compiled with ADAPTIVE (set 2: the
    // refinement's state), no silhouettes (the box's outline is where the
    // key's "met the box" changes).
    let adaptive = if settings.adaptive > 0.0 {
        let state = Adaptive::new(inputs.ctx, "raycast-compute", settings.adaptive, inputs.width, inputs.height, false)?;
        let key = settings.compute_key(facts, &target_set.desc, Some(&state.desc));
        Some((state, crate::algo::pipelines::get(inputs.ctx, &key)?))
    } else {
        None
    };
    Ok(Box::new(RaycastCompute {
        adaptive,
        rect: screen::NO_PIXELS,
        res,
        settings,
        pipeline,
        key,
        target_set,
        push: bytemuck::Zeroable::zeroed(),
        groups: [0, 0, 1],
        written: screen::NO_PIXELS,
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
    /// The frame's push constants (with ADAPTIVE, its `frame`).
    push: AdaptiveFrame,
    /// Workgroups dispatched (over the box's tiles).
    groups: [u32; 3],
    /// The pixels the plain march's workgroups write (`storage_target`).
    written: [u32; 4],
    pixels: u64,
    /// `adaptive=TOL`: the refinement's state and the march casting its
    /// lattice points; the frame's rectangle (the box's pixels).
    adaptive: Option<(Adaptive, Arc<Pipeline>)>,
    rect: [u32; 4],
    ctx: Arc<crate::vk::Context>,
}

impl RenderMethod for RaycastCompute {
    fn prepare(&mut self, view: &View, _phases: &mut Phases) -> Result<()> {
        let (w, h) = (view.width, view.height);
        // The box's pixels (its place in the view; the whole image when the
        // box is cut by the eye plane), and only the tiles over them.
        let box_rect = match self.res.on_screen(view) {
            BoxOnScreen::Hidden => screen::NO_PIXELS,
            BoxOnScreen::Whole { rect } => rect,
            BoxOnScreen::Cut => [0, 0, w.saturating_sub(1), h.saturating_sub(1)],
        };
        let (base, groups) = screen::groups_over(box_rect, WORKGROUP);
        // Rows interleaved over the device's runs of workgroups
        // (algo::screen::interleaved_rows).
        let runs = self.ctx.info.compute_runs();
        self.groups = [groups[0], screen::interleaved_rows(groups[1], runs), 1];
        self.written = screen::pixels_of_groups(base, groups, WORKGROUP, [w, h]);
        self.push.frame = self.res.frame(view, true, [base[0], base[1]], groups[1], runs);
        if let Some((state, _)) = &mut self.adaptive {
            self.rect = box_rect;
            state.frame(self.rect, [w, h])?;
            let close = super::key_close(self.res.brick_pixels(view, self.settings.brick as f64));
            // The rect; the step (and for step 8 its lattice's rows) are set per pass in record.
            self.push = AdaptiveFrame { frame: self.res.frame(view, true, [0, 0], 0, runs), close, rect: self.rect, cast_step: 0 };
        }
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
        if let Some((state, pipeline)) = &mut self.adaptive {
            rec.storage_target(target, self.rect);
            let (set0, push, pipeline) = (&self.res.set, self.push, &*pipeline);
            state.record(rec, target, counter, |rec, state_set, step, rows, counter| {
                rec.bind_compute(pipeline, &[set0, set, state_set])?;
                let p = AdaptiveFrame { cast_step: step, frame: Frame { rows, ..push.frame }, ..push };
                rec.push_constants(pipeline, bytemuck::bytes_of(&p), counter);
                Ok(())
            })?;
            self.res.record_counters_to_host(rec);
            return Ok(());
        }
        rec.storage_target(target, self.written);
        if self.groups[0] > 0 && self.groups[1] > 0 {
            rec.bind_compute(&self.pipeline, &[&self.res.set, set])?;
            rec.push_constants(&self.pipeline, bytemuck::bytes_of::<Frame>(&self.push.frame), counter);
            rec.dispatch(self.groups)?;
        }
        self.res.record_counters_to_host(rec);
        Ok(())
    }

    fn work(&self) -> Work {
        let w = self.res.work(self.pixels);
        match &self.adaptive {
            Some((state, _)) => {
                let [x0, y0, x1, y1] = self.rect;
                let rect_pixels = if x0 > x1 || y0 > y1 { 0 } else { u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) };
                state.work(w.with("pixels_in_rect", rect_pixels))
            }
            None => w,
        }
    }

    fn details(&self) -> serde_json::Value {
        let mut d = self.res.details(
            &self.settings,
            json!({
                "name": "compute",
                "workgroup": WORKGROUP,
                "counter_atomics": if self.ctx.info.compute_subgroup_arithmetic { "per subgroup" } else { "per ray" },
                "pipeline": { "key": self.key.id(), "name": self.key.name() },
            }),
        );
        if let Some((state, _)) = &self.adaptive {
            let [x0, y0, x1, y1] = self.rect;
            let rect_pixels = if x0 > x1 || y0 > y1 { 0 } else { u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) };
            d["adaptive"] = state.details(rect_pixels);
            d["adaptive"]["key"] = json!({ "near_bricks": super::KEY_NEAR, "close_bricks": self.push.close });
        }
        d
    }

    fn table_build_ms(&self) -> f64 {
        self.res.table_build_ms
    }

    /// Adaptive refinement's time per pass (`algo::adaptive::PASS_PHASES`).
    fn after_frame(&mut self, phases: &mut Phases) -> Result<()> {
        if let Some((state, _)) = &self.adaptive {
            for (name, ms) in state.device_phases()? {
                phases.add(name, ms);
            }
        }
        Ok(())
    }
}
