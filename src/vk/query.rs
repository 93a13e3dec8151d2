//! GPU timestamps and pipeline-statistics queries for one frame. Timestamps
//! give device time; statistics give deterministic work counts: input
//! assembly, vertex, geometry (when the device has geometry shaders),
//! clipping, fragment and compute invocations. Results come back in
//! flag-bit order, as the spec requires, so the flags are kept sorted.

use std::sync::Arc;

use ash::vk;
use serde::Serialize;

use super::commands::CommandRecorder;
use super::error::{Check, VkError, VkResult};
use super::Context;

/// The statistics we may collect, in flag-bit order (the order results come
/// back); the geometry ones only when the device has geometry shaders.
const STATS: [vk::QueryPipelineStatisticFlags; 8] = [
    vk::QueryPipelineStatisticFlags::INPUT_ASSEMBLY_VERTICES,
    vk::QueryPipelineStatisticFlags::INPUT_ASSEMBLY_PRIMITIVES,
    vk::QueryPipelineStatisticFlags::VERTEX_SHADER_INVOCATIONS,
    vk::QueryPipelineStatisticFlags::GEOMETRY_SHADER_INVOCATIONS,
    vk::QueryPipelineStatisticFlags::GEOMETRY_SHADER_PRIMITIVES,
    vk::QueryPipelineStatisticFlags::CLIPPING_PRIMITIVES,
    vk::QueryPipelineStatisticFlags::FRAGMENT_SHADER_INVOCATIONS,
    vk::QueryPipelineStatisticFlags::COMPUTE_SHADER_INVOCATIONS,
];

/// Work counts between `FrameQueries::begin` and `end`. Counters the device
/// cannot collect (geometry ones without geometry shaders) stay 0.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct PipelineStats {
    pub input_vertices: u64,
    pub input_primitives: u64,
    pub vertex_invocations: u64,
    pub clipping_primitives: u64,
    pub fragment_invocations: u64,
    pub geometry_invocations: u64,
    pub geometry_primitives: u64,
    pub compute_invocations: u64,
}

impl PipelineStats {
    fn set(&mut self, flag: vk::QueryPipelineStatisticFlags, value: u64) {
        use vk::QueryPipelineStatisticFlags as F;
        let field = match flag {
            F::INPUT_ASSEMBLY_VERTICES => &mut self.input_vertices,
            F::INPUT_ASSEMBLY_PRIMITIVES => &mut self.input_primitives,
            F::VERTEX_SHADER_INVOCATIONS => &mut self.vertex_invocations,
            F::GEOMETRY_SHADER_INVOCATIONS => &mut self.geometry_invocations,
            F::GEOMETRY_SHADER_PRIMITIVES => &mut self.geometry_primitives,
            F::CLIPPING_PRIMITIVES => &mut self.clipping_primitives,
            F::FRAGMENT_SHADER_INVOCATIONS => &mut self.fragment_invocations,
            F::COMPUTE_SHADER_INVOCATIONS => &mut self.compute_invocations,
            _ => return,
        };
        *field = value;
    }
}

pub struct FrameQueries {
    timestamps: vk::QueryPool,
    stats: Option<vk::QueryPool>,
    /// The flags of `stats`, in bit order.
    stat_flags: Vec<vk::QueryPipelineStatisticFlags>,
    /// Record the statistics query (`set_statistics`); timestamps always.
    statistics: bool,
    period_ns: f64,
    valid_mask: u64,
    ctx: Arc<Context>,
}

impl FrameQueries {
    pub fn new(ctx: &Arc<Context>) -> VkResult<Self> {
        let d = &ctx.device;
        let ts_info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2);
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let timestamps = unsafe { d.create_query_pool(&ts_info, None) }.check("vkCreateQueryPool(timestamps)")?;
        let geometry = ctx.info.features.geometry_shader;
        let stat_flags: Vec<_> = STATS
            .iter()
            .copied()
            .filter(|&f| {
                geometry
                    || !(f == vk::QueryPipelineStatisticFlags::GEOMETRY_SHADER_INVOCATIONS
                        || f == vk::QueryPipelineStatisticFlags::GEOMETRY_SHADER_PRIMITIVES)
            })
            .collect();
        let stats = if ctx.info.pipeline_statistics {
            let flags = stat_flags.iter().fold(vk::QueryPipelineStatisticFlags::empty(), |a, &f| a | f);
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::PIPELINE_STATISTICS)
                .query_count(1)
                .pipeline_statistics(flags);
            // SAFETY: the create info and everything it points to live for the
            // call; the device outlives the handle (the owner holds the Context in
            // an Arc) and the handle is destroyed once, by its owner's Drop or the
            // error path below.
            match unsafe { d.create_query_pool(&info, None) } {
                Ok(p) => Some(p),
                Err(result) => {
                    // SAFETY: the handle was created just above, was never used or
                    // submitted, and is destroyed once here, on the error path (the wrapper
                    // that would own it is not built).
                    unsafe { d.destroy_query_pool(timestamps, None) };
                    return Err(super::VkError::Call { what: "vkCreateQueryPool(statistics)", result });
                }
            }
        } else {
            None
        };
        let bits = ctx.info.timestamp_valid_bits;
        let valid_mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        Ok(FrameQueries { timestamps, stats, stat_flags, statistics: true, period_ns: ctx.info.timestamp_period_ns as f64, valid_mask, ctx: ctx.clone() })
    }

    /// Whether the following recordings begin and end the statistics query
    /// (on at creation). Off, a frame carries timestamps only and `results`
    /// gives no statistics: frames whose statistics nobody reads need not
    /// make the device count (docs/frame-cost.md has what it measured to).
    /// Change it only between a frame's `results` and the next `begin`.
    pub fn set_statistics(&mut self, on: bool) {
        self.statistics = on;
    }

    /// The statistics pool, when this device has one and it is switched on.
    fn active_stats(&self) -> Option<vk::QueryPool> {
        self.stats.filter(|_| self.statistics)
    }

    /// Reset both pools; record outside a render pass, before `begin`.
    pub fn reset(&self, rec: &CommandRecorder) {
        let cmd = rec.raw;
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_reset_query_pool(cmd, self.timestamps, 0, 2);
            if let Some(p) = self.stats {
                self.ctx.device.cmd_reset_query_pool(cmd, p, 0, 1);
            }
        }
    }

    pub fn begin(&self, rec: &CommandRecorder) {
        let cmd = rec.raw;
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            self.ctx.device.cmd_write_timestamp2(cmd, vk::PipelineStageFlags2::TOP_OF_PIPE, self.timestamps, 0);
            if let Some(p) = self.active_stats() {
                self.ctx.device.cmd_begin_query(cmd, p, 0, vk::QueryControlFlags::empty());
            }
        }
    }

    pub fn end(&self, rec: &CommandRecorder) {
        let cmd = rec.raw;
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe {
            if let Some(p) = self.active_stats() {
                self.ctx.device.cmd_end_query(cmd, p, 0);
            }
            self.ctx.device.cmd_write_timestamp2(cmd, vk::PipelineStageFlags2::BOTTOM_OF_PIPE, self.timestamps, 1);
        }
    }

    /// GPU milliseconds between `begin` and `end`, and the statistics (none
    /// while `set_statistics(false)`), after
    /// the frame's fence has signalled. Results are read without
    /// VK_QUERY_RESULT_WAIT_BIT, which could block forever on a query that
    /// was never submitted: called too early, this is an error instead.
    pub fn results(&self) -> VkResult<(f64, Option<PipelineStats>)> {
        let d = &self.ctx.device;
        let not_ready = |what: &'static str| {
            move |result| match result {
                vk::Result::NOT_READY => VkError::Invalid(format!(
                    "{what}: query results not available (was the frame submitted and its recorder waited for?)"
                )),
                result => VkError::Call { what, result },
            }
        };
        let mut ts = [0u64; 2];
        // SAFETY: the pool is live on this device and the output holds every
        // result read (64-bit each, TYPE_64; statistics: one [u64; 8] for at most
        // 8 counters). Read without WAIT_BIT, an unfinished query is NOT_READY,
        // an error, never a block.
        unsafe { d.get_query_pool_results(self.timestamps, 0, &mut ts, vk::QueryResultFlags::TYPE_64) }
            .map_err(not_ready("vkGetQueryPoolResults(timestamps)"))?;
        let ticks = (ts[1] & self.valid_mask).wrapping_sub(ts[0] & self.valid_mask) & self.valid_mask;
        let gpu_ms = ticks as f64 * self.period_ns * 1e-6;
        let stats = match self.active_stats() {
            Some(p) => {
                let mut v = [0u64; STATS.len()];
                let n = self.stat_flags.len();
                // One query (a one-element slice of [u64; 8]) whose result is
                // `n` <= 8 consecutive u64 values.
                // SAFETY: the pool is live on this device and the output holds every
                // result read (64-bit each, TYPE_64; statistics: one [u64; 8] for at most
                // 8 counters). Read without WAIT_BIT, an unfinished query is NOT_READY,
                // an error, never a block.
                unsafe {
                    d.get_query_pool_results(p, 0, std::slice::from_mut(&mut v), vk::QueryResultFlags::TYPE_64)
                }
                .map_err(not_ready("vkGetQueryPoolResults(statistics)"))?;
                let mut stats = PipelineStats::default();
                for (&f, &value) in self.stat_flags.iter().zip(&v[..n]) {
                    stats.set(f, value);
                }
                Some(stats)
            }
            None => None,
        };
        Ok((gpu_ms, stats))
    }
}

impl Drop for FrameQueries {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe {
            self.ctx.device.destroy_query_pool(self.timestamps, None);
            if let Some(p) = self.stats {
                self.ctx.device.destroy_query_pool(p, None);
            }
        }
    }
}
