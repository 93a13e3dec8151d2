//! `raycast-fragment`: the lab's three passes (see `super`). Pass 1 draws
//! the box's front faces into an RGBA32F target (entry points, voxel
//! coordinates, alpha 1 where covered), pass 2 its back faces into another
//! (exit points), pass 3 a full-screen triangle whose fragments march from
//! entry to exit into the runner's target. The box is convex, so culling
//! alone picks one front and one back face per pixel: no depth buffer.

use std::sync::Arc;

use anyhow::{bail, Result};
use serde_json::json;

use crate::algo::settings::MethodSettings;
use super::{BoxOnScreen, Frame, Settings, VolumeResources, COMPARE, OPTIONS, STRESS, SUITE, SWEEP};
use crate::algo::method::{DataKind, Feature, MethodInfo, MethodInputs, Phases, RenderMethod, SceneData, View, Work};
use crate::vk::{
    ColorAttachment, CommandRecorder, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, Image, ImageUse, Pipeline, PipelineKey,
    Sampler, UploadCounter,
};
use crate::vk::{Cull, Stages};

pub const METHOD: MethodInfo = MethodInfo {
    name: "raycast-fragment",
    data: DataKind::Volume,
    summary: "GPU ray casting as in the lab: box front/back faces into entry/exit targets, then a full-screen march",
    options: OPTIONS,
    // The march counts its samples with storage-buffer atomics.
    features: &[Feature::FragmentStoresAndAtomics],
    sweep: SWEEP,
    compare: COMPARE,
    stress: STRESS,
    suite: SUITE,
    published: &[super::kruger_westermann("raycast-fragment")],
    family: super::FAMILY,
    create,
};

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Volume(vol) = inputs.data else { bail!("raycast-fragment renders volumes only") };
    let ctx = inputs.ctx;
    let settings = Settings::from_options(inputs.options)?;
    if settings.adaptive > 0.0 {
        // Why the fragment path does not take it: docs/methods.md,
        // "Adaptive image-space refinement".
        bail!(
            "raycast-fragment: adaptive={} is not supported: this variant marches one ray per fragment of the \
             box's rasterized faces, i.e. per covered pixel, from entry and exit points rasterized at every pixel; \
             adaptive refinement marches only at lattice points that each level's decisions choose on the device \
             and fills the blocks between them, which a draw could do only as indirect point draws over those lists \
             with the entry and exit points still rasterized at full resolution (no longer this variant). \
             raycast-compute:adaptive={} marches the same rays with the same integration",
            settings.adaptive,
            settings.adaptive
        );
    }
    let res = VolumeResources::new(ctx, vol, inputs.samples, inputs.tf, &settings, inputs.counter)?;
    let entry = Image::render_target(ctx, "ray entry points", inputs.width, inputs.height)?;
    let exit = Image::render_target(ctx, "ray exit points", inputs.width, inputs.height)?;
    if !entry.is_sampled() {
        bail!("device '{}' cannot sample RGBA32F render targets (needed for the entry/exit points)", ctx.info.name);
    }
    let sampler = Sampler::nearest_clamp(ctx, "entry/exit")?;
    let fs = Stages::FRAGMENT;
    let points_desc = DescriptorSetDesc::new(&[(DescriptorKind::CombinedImageSampler, fs), (DescriptorKind::CombinedImageSampler, fs)]);
    let points_set = DescriptorSet::new(
        ctx,
        "entry/exit points",
        &points_desc,
        &[DescriptorResource::CombinedImageSampler(&entry, &sampler), DescriptorResource::CombinedImageSampler(&exit, &sampler)],
    )?;
    let facts = res.shader_facts(ctx);
    let front_key = settings.box_key(facts, Cull::Back);
    let back_key = settings.box_key(facts, Cull::Front);
    let march_key = settings.fragment_march_key(facts, &points_desc);
    let get = |k: &PipelineKey| crate::algo::pipelines::get(ctx, k);
    Ok(Box::new(RaycastFragment {
        front: get(&front_key)?,
        back: get(&back_key)?,
        march: get(&march_key)?,
        march_key,
        placement: BoxOnScreen::Cut,
        res,
        settings,
        entry,
        exit,
        _sampler: sampler,
        points_set,
        box_push: bytemuck::Zeroable::zeroed(),
        march_push: bytemuck::Zeroable::zeroed(),
        pixels: inputs.width as u64 * inputs.height as u64,
    }))
}

pub struct RaycastFragment {
    front: Arc<Pipeline>,
    back: Arc<Pipeline>,
    march: Arc<Pipeline>,
    march_key: PipelineKey,
    /// Where the box lies in the frame's view: which march is drawn.
    placement: BoxOnScreen,
    res: VolumeResources,
    settings: Settings,
    entry: Image,
    exit: Image,
    _sampler: Sampler,
    points_set: DescriptorSet,
    box_push: Frame,
    march_push: Frame,
    pixels: u64,
}

impl RenderMethod for RaycastFragment {
    fn prepare(&mut self, view: &View, _phases: &mut Phases) -> Result<()> {
        self.box_push = self.res.frame(view, false, [0; 2], 0, 0);
        self.march_push = self.res.frame(view, true, [0; 2], 0, 0);
        self.placement = self.res.on_screen(view);
        Ok(())
    }

    fn upload(&mut self, _counter: &mut UploadCounter) -> Result<()> {
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, _view: &View, counter: &mut UploadCounter) -> Result<()> {
        self.res.record_clear(rec);
        for (image, pipeline) in [(&self.entry, &self.front), (&self.exit, &self.back)] {
            rec.begin_rendering_targets(&[ColorAttachment { image, clear: Some([0.0; 4]) }])?;
            rec.bind_graphics(pipeline, &[&self.res.set])?;
            rec.push_constants(pipeline, bytemuck::bytes_of(&self.box_push), counter);
            rec.draw(36);
            rec.end_rendering();
            rec.image_barrier(image, ImageUse::Sampled);
        }
        rec.begin_rendering(target, [0.0; 4]);
        // The march runs only over the box's pixels: a fragment whose ray
        // misses still runs the whole shader masked on llvmpipe. One
        // scissored triangle, not the box's faces: on llvmpipe a block of
        // pixels cut by an edge between two faces runs the march once per
        // face.
        let rect = match self.placement {
            BoxOnScreen::Hidden => None,
            BoxOnScreen::Whole { rect } => Some(rect),
            BoxOnScreen::Cut => Some([0, 0, target.width - 1, target.height - 1]),
        };
        if let Some(rect) = rect {
            rec.set_scissor(rect);
            rec.bind_graphics(&self.march, &[&self.res.set, &self.points_set])?;
            rec.push_constants(&self.march, bytemuck::bytes_of(&self.march_push), counter);
            rec.draw(3);
        }
        rec.end_rendering();
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
                "name": "fragment",
                "passes": ["box front faces -> entry (RGBA32F)", "box back faces -> exit (RGBA32F)", "full-screen march"],
                "pipeline": { "key": self.march_key.id(), "name": self.march_key.name() },
            }),
        )
    }

    fn table_build_ms(&self) -> f64 {
        self.res.table_build_ms
    }
}
