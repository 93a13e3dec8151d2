//! `resident-gpusort` (beyond the thesis): `resident` with the visibility
//! sort on the device. The cells, their centroids and the static strips are
//! uploaded once; each frame a compute radix sort (`device_sort`) orders the
//! cells by centroid depth into a device-local buffer that the vertex stage
//! of `resident.vert` reads in place, so nothing but the camera crosses per
//! frame (the sort's 32 bytes and the draw's frame constants, all push
//! constants). The vertex stage runs balanced's per-tet work per vertex
//! from the stored cells (`resident` instead expands the order into
//! balanced's records in a compute pass, once per tet); the order equals
//! the CPU's centroid order exactly, so the image is `resident`'s. The sort's GPU time is reported as the phase `sort_gpu`.
//!
//! Only the centroid order: MPVO's order is a graph traversal, not a sort,
//! and is not built on the device; `sort=mpvo` is refused when the spec is
//! parsed.

use std::sync::Arc;

use anyhow::Result;

use super::balanced::VERTICES_PER_CELL;
use super::device_sort::{DeviceCentroidSort, SortCamera};
use super::render;
use super::resident::{cells_and_order_set, resident_pipeline, upload_cell_chunks, FLOATS_PER_STORED_CELL};
use crate::algo::chunks::{ChunkLimits, TexelChunks};
use super::sort::SortKind;
use super::{centroids_relative_f32, CellProjector, DrawSettings, StaticIndices, MAX_INDICES_PER_CELL};
use crate::algo::tet_mesh::{render_origin, FrameSetup};
use crate::algo::host_memory::HostMemory;
use crate::algo::integrate::IntegrationTables;
use crate::algo::method::{DataKind, Family, Feature, MethodInfo, MethodInputs, Options, RenderMethod};
use crate::mesh::TetMesh;
use crate::vk::{
    CommandRecorder, Context, DescriptorSet, Pipeline, PipelineKey, UploadCounter,
    VkResult,
};

/// The name of the sort's GPU-time phase (`time_ms.sort_gpu`).
pub const SORT_PHASE: &str = "sort_gpu";

/// The registry entry: cell projection's options, sweeps and bounds, with
/// the option sets that name MPVO left out.
pub const METHOD: MethodInfo = MethodInfo {
    name: "resident-gpusort",
    data: DataKind::TetMesh,
    summary: "resident with the centroid sort on the device (compute radix sort): only the camera crosses per frame",
    options: render::KNOWN_EXITS_OPTIONS_WITHOUT_CULL,
    features: &[Feature::DepthClamp],
    sweep: SWEEP,
    compare: render::COMPARE,
    stress: STRESS,
    suite: &[],
    published: &[],
    // Draws every cell in its own order: no culling option.
    family: Family { check, ..render::FAMILY },
    create,
};

/// `render::SWEEP` without its `sort=mpvo` sets (a unit test keeps the two in step).
const SWEEP: &[&str] = &[
    "integrator=average,interpolation=paper,sort=centroid",
    "integrator=preint,table_size=128,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=128,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=512,interpolation=paper,sort=centroid",
    "integrator=ppi,table_size=1024,interpolation=paper,sort=centroid",
    "integrator=linear-exact,interpolation=paper,sort=centroid",
    "integrator=average,interpolation=exact,sort=centroid",
    "integrator=preint,table_size=128,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=128,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=512,interpolation=exact,sort=centroid",
    "integrator=ppi,table_size=1024,interpolation=exact,sort=centroid",
    "integrator=linear-exact,interpolation=exact,sort=centroid",
];

/// `render::STRESS` without its `sort=mpvo` sets.
const STRESS: &[&str] = &[
    "integrator=average,interpolation=paper,sort=centroid",
    "integrator=preint,interpolation=paper,sort=centroid",
    "integrator=ppi,interpolation=paper,sort=centroid",
    "integrator=linear-exact,interpolation=paper,sort=centroid",
    "integrator=average,interpolation=exact,sort=centroid",
    "integrator=preint,interpolation=exact,sort=centroid",
    "integrator=ppi,interpolation=exact,sort=centroid",
    "integrator=linear-exact,interpolation=exact,sort=centroid",
];

/// Cell projection's checks, and the centroid order only.
fn check(options: &Options) -> Result<()> {
    let settings = <render::Settings as crate::algo::settings::MethodSettings>::from_options(options)?;
    anyhow::ensure!(
        settings.sort == SortKind::Centroid,
        "option 'sort' = {}: the device sort builds the centroid order only (sort=centroid; MPVO runs on the CPU: \
         use resident:sort=mpvo)",
        settings.sort.name()
    );
    Ok(())
}

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let bytes = render::DeviceBytesPerCell {
        frame: 0,
        fixed: MAX_INDICES_PER_CELL * 4 + FLOATS_PER_STORED_CELL * 4 + super::device_sort::DEVICE_BYTES_PER_CELL,
        host: 0,
    };
    render::CellProjection::create(inputs, bytes, |ctx, mesh, tables, draw, counter| {
        Ok(Box::new(ResidentGpuSort::new(ctx, mesh, tables, draw, counter)?))
    })
}

pub struct ResidentGpuSort {
    cells: usize,
    set: DescriptorSet,
    sort: DeviceCentroidSort,
    cell_chunks: TexelChunks,
    indices: StaticIndices,
    pipeline: Arc<Pipeline>,
    pipeline_key: PipelineKey,
}

impl ResidentGpuSort {
    pub fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tables: &IntegrationTables,
        draw: DrawSettings,
        counter: &mut UploadCounter,
    ) -> VkResult<Self> {
        let n = mesh.tets.len();
        // The same f64 -> f32 centroids as the CPU's centroid sort.
        let centroids = centroids_relative_f32(mesh, render_origin(mesh));
        let sort = DeviceCentroidSort::new(ctx, "resident-gpusort", &centroids, counter)?;
        let cells = upload_cell_chunks(ctx, "resident-gpusort cells", mesh, &ChunkLimits::of(ctx)?, counter)?;
        let indices = StaticIndices::upload(ctx, "resident-gpusort indices", draw.primitives, n, counter)?;
        let set = cells_and_order_set(ctx, "resident-gpusort cells and order", &cells, sort.order())?;
        let (pipeline, pipeline_key) = resident_pipeline(ctx, tables, draw, &cells)?;
        Ok(ResidentGpuSort { cells: n, set, sort, cell_chunks: cells, indices, pipeline, pipeline_key })
    }
}

impl CellProjector for ResidentGpuSort {
    fn cells(&self) -> usize {
        self.cells
    }
    fn vertices_per_cell(&self) -> usize {
        VERTICES_PER_CELL
    }
    fn floats_per_cell(&self) -> usize {
        0
    }
    fn host_bytes(&self, _memory: &mut HostMemory) {
        // Cells, centroids and the order live on the device only.
    }

    fn pipeline_key(&self) -> &PipelineKey {
        &self.pipeline_key
    }
    fn device_chunks(&self) -> serde_json::Value {
        let (centroid_buffers, centroids_per_buffer) = self.sort.centroid_buffers();
        serde_json::json!({
            "cell_buffers": self.cell_chunks.buffers.len(),
            "cells_per_buffer": self.cell_chunks.per_chunk,
            "centroid_buffers": centroid_buffers,
            "centroids_per_buffer": centroids_per_buffer,
        })
    }

    /// Nothing: the order is made on the device.
    fn pack(&mut self, _order: &[u32], _frame: &FrameSetup) {}

    fn upload(&mut self, _counter: &mut UploadCounter) -> VkResult<()> {
        Ok(())
    }

    fn sorts_on_device(&self) -> bool {
        true
    }

    fn record_before_draw(&self, rec: &CommandRecorder, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        self.sort.record(rec, &SortCamera::from_frame(frame), counter)
    }

    fn record_draw(&self, rec: &CommandRecorder, tables: &IntegrationTables, frame: &FrameSetup, counter: &mut UploadCounter) -> VkResult<()> {
        let sets: [&DescriptorSet; 2] = [&tables.set, &self.set];
        rec.bind_graphics(&self.pipeline, &sets)?;
        rec.push_constants(&self.pipeline, bytemuck::bytes_of(&frame.constants), counter);
        self.indices.draw(rec, self.cells);
        Ok(())
    }

    fn device_phases(&self) -> VkResult<Vec<(&'static str, f64)>> {
        Ok(vec![(SORT_PHASE, self.sort.gpu_ms()?)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The option sets are cell projection's, less those naming MPVO.
    #[test]
    fn option_sets_are_render_s_centroid_sets() {
        let centroid = |sets: &[&'static str]| -> Vec<&'static str> { sets.iter().copied().filter(|s| !s.contains("sort=mpvo")).collect() };
        assert_eq!(SWEEP, centroid(render::SWEEP).as_slice());
        assert_eq!(STRESS, centroid(render::STRESS).as_slice());
        assert!(render::COMPARE.iter().all(|s| !s.contains("mpvo")));
    }

    #[test]
    fn the_sort_phase_is_a_device_phase() {
        assert!(SORT_PHASE.ends_with(crate::algo::method::DEVICE_PHASE_SUFFIX));
    }

    #[test]
    fn mpvo_is_refused_naming_the_option() {
        // Through the method's own entry (the registry's parse ends here too).
        let e = METHOD.options_from([("sort", "mpvo")]).unwrap_err().to_string();
        assert!(e.contains("resident-gpusort") && e.contains("option 'sort'") && e.contains("centroid"), "{e}");
        METHOD.options_from([("sort", "centroid")]).unwrap();
    }
}
