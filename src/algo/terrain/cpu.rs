//! `hm-cpu`: HM's original placement of the PC-cell work. Every frame the
//! CPU selects the level per block, tessellates each active PC cell
//! against its TB chains (`HybridModel::tessellate`) and uploads the
//! triangles (as indices into the static geometry buffer, 12 bytes per
//! triangle) to a host-visible index buffer, sized at set-up for the
//! largest frame possible. NC cells and TINs come from static indices.

use anyhow::{bail, Result};
use serde_json::json;

use super::{TerrainScene, COMPARE, OPTIONS, SWEEP};
use crate::algo::method::{DataKind, MethodInfo, MethodInputs, Phases, RenderMethod, SceneData, View, Work};
use crate::vk::{Buffer, BufferDesc, CommandRecorder, Image, UploadClass, UploadCounter};
use crate::vk::BufferUsage;

pub const METHOD: MethodInfo = MethodInfo {
    name: "hm-cpu",
    data: DataKind::Terrain,
    summary: "hybrid terrain meshes, HM: active PC cells tessellated on the CPU every frame and uploaded as triangles",
    options: OPTIONS,
    features: &[],
    sweep: SWEEP,
    compare: COMPARE,
    suite: &[],
    stress: &[],
    // No stress cases for terrains (their error is the method's own).
    published: &[],
    family: super::FAMILY,
    create,
};

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::Terrain(map) = inputs.data else { bail!("hm-cpu renders terrains only") };
    let scene = TerrainScene::new(inputs.ctx, map, inputs.options, inputs.width, inputs.height, inputs.counter)?;
    // The largest frame: per block, its level with the most PC triangles.
    let m = &scene.model;
    let mut tris = Vec::new();
    let mut most = 0usize;
    for b in 0..m.blocks[0] as usize * m.blocks[1] as usize {
        let mut block_most = 0;
        for (k, l) in m.levels.iter().enumerate() {
            tris.clear();
            for pc in &l.pc[l.pc_by_block[b].start as usize..l.pc_by_block[b].end as usize] {
                m.tessellate(k, pc, &mut tris)?;
            }
            block_most = block_most.max(tris.len());
        }
        most += block_most;
    }
    let capacity = (most.max(3) * 4) as u64;
    let buffer = Buffer::new(inputs.ctx, BufferDesc::upload("hm-cpu PC triangles", capacity, BufferUsage::INDEX))?;
    Ok(Box::new(HmCpu { scene, buffer, indices: Vec::with_capacity(most), capacity_indices: most }))
}

pub struct HmCpu {
    scene: TerrainScene,
    buffer: Buffer,
    /// This frame's PC triangles.
    indices: Vec<u32>,
    capacity_indices: usize,
}

impl RenderMethod for HmCpu {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        self.scene.select(view, phases);
        let t0 = std::time::Instant::now();
        self.indices.clear();
        let m = &self.scene.model;
        for &(level, i) in &self.scene.active.pc_cells {
            m.tessellate(level as usize, &m.levels[level as usize].pc[i as usize], &mut self.indices)?;
        }
        phases.ended("tessellate", t0.elapsed().as_secs_f64() * 1e3);
        if self.indices.len() > self.capacity_indices {
            bail!("hm-cpu: {} PC indices exceed the {} sized for", self.indices.len(), self.capacity_indices);
        }
        Ok(())
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        if !self.indices.is_empty() {
            self.buffer.write(0, bytemuck::cast_slice(&self.indices), counter, UploadClass::FrameCells)?;
        }
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, view: &View, counter: &mut UploadCounter) -> Result<()> {
        let pc_push = self.scene.record_static(rec, target, view, counter)?;
        if !self.indices.is_empty() {
            rec.bind_index_buffer_u32(&self.buffer);
            rec.push_constants(&self.scene.pipeline, bytemuck::bytes_of(&pc_push), counter);
            rec.draw_indexed_range(0, self.indices.len() as u32);
        }
        rec.end_rendering();
        Ok(())
    }

    fn work(&self) -> Work {
        let a = &self.scene.active;
        let pc_tris = self.indices.len() as u64 / 3;
        Work::default()
            .with("nc_cells", a.nc_cells)
            .with("pc_cells", a.pc_cells.len() as u64)
            .with("pc_triangles", pc_tris)
            .with("skirt_triangles", a.skirt_triangles)
            .with("triangles", a.nc_cells * 2 + pc_tris + self.scene.tin_triangles() + a.skirt_triangles)
    }

    fn details(&self) -> serde_json::Value {
        self.scene.details(json!({
            "name": "cpu",
            "pc_upload": "indices into the static geometry, 3 x u32 per triangle, every frame",
            "pc_capacity_triangles": self.capacity_indices / 3,
        }))
    }

    /// The fingerprint of this frame's PC triangles (`tables::triangle_digest`),
    /// which the GPU methods' must equal.
    fn diagnostics(&mut self, _view: &View) -> Result<Option<serde_json::Value>> {
        let (triangles, digest) = super::tables::triangle_digest(&self.indices);
        Ok(Some(json!({ "pc_triangles": triangles, "pc_digest": digest, "tessellation_errors": 0 })))
    }

    fn table_build_ms(&self) -> f64 {
        self.scene.build_ms
    }


}
