//! A method's own timestamp queries: a small pool of timestamps that a
//! method writes around its passes (e.g. a device sort) so that the pass's
//! GPU time is reported as its own phase, beside the frame's `gpu` time that
//! `query::FrameQueries` measures around everything. Separate from
//! `FrameQueries` so that the runner's pool stays the runner's: a method
//! resets and writes its pool in its own command recording and reads it
//! after the frame's fence has signalled.

use std::sync::Arc;

use ash::vk;

use super::commands::CommandRecorder;
use super::error::{Check, VkError, VkResult};
use super::types::TimestampAt;
use super::Context;

pub struct TimestampPool {
    raw: vk::QueryPool,
    count: u32,
    name: String,
    period_ns: f64,
    valid_mask: u64,
    ctx: Arc<Context>,
}

impl TimestampPool {
    /// A pool of `count` timestamps named `name` (debug name and errors).
    /// On a queue without timestamps the pool exists but `read` gives
    /// `None` and `elapsed_ms` an error saying so.
    pub fn new(ctx: &Arc<Context>, name: &str, count: u32) -> VkResult<Self> {
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(count.max(1));
        // SAFETY: the create info and everything it points to live for the
        // call; the device outlives the handle (the owner holds the Context in
        // an Arc) and the handle is destroyed once, by its owner's Drop or the
        // error path below.
        let raw = unsafe { ctx.device.create_query_pool(&info, None) }.check("vkCreateQueryPool(method timestamps)")?;
        ctx.set_name(raw, name);
        let bits = ctx.info.timestamp_valid_bits;
        let valid_mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        Ok(TimestampPool {
            raw,
            count,
            name: name.to_string(),
            period_ns: ctx.info.timestamp_period_ns as f64,
            valid_mask,
            ctx: ctx.clone(),
        })
    }

    /// Reset every timestamp; record outside a render pass, before `write`.
    pub fn reset(&self, rec: &CommandRecorder) {
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_reset_query_pool(rec.raw, self.raw, 0, self.count) };
    }

    /// Write timestamp `index` at `at` (see `TimestampAt`).
    pub fn write(&self, rec: &CommandRecorder, index: u32, at: TimestampAt) -> VkResult<()> {
        if index >= self.count {
            return Err(VkError::Invalid(format!("timestamp {index} of '{}', which holds {}", self.name, self.count)));
        }
        // SAFETY: the command buffer is a recorder's own, recording between its
        // `begin` and submit (the recorder's state machine); every handle recorded
        // is live, borrowed for the call and kept alive by its owner until the
        // submission is waited for.
        unsafe { self.ctx.device.cmd_write_timestamp2(rec.raw, at.to_vk(), self.raw, index) };
        Ok(())
    }

    /// Every timestamp's raw ticks, read without VK_QUERY_RESULT_WAIT_BIT
    /// (see `elapsed_ms`).
    fn ticks(&self) -> VkResult<Vec<u64>> {
        if self.ctx.info.timestamp_valid_bits == 0 {
            return Err(VkError::Unsupported { device: self.ctx.info.name.clone(), what: "timestamp queries on its queue".into() });
        }
        let mut ts = vec![0u64; self.count as usize];
        // SAFETY: the pool is live on this device and the output holds every
        // result read (64-bit each, TYPE_64; statistics: one [u64; 8] for at most
        // 8 counters). Read without WAIT_BIT, an unfinished query is NOT_READY,
        // an error, never a block.
        unsafe { self.ctx.device.get_query_pool_results(self.raw, 0, &mut ts, vk::QueryResultFlags::TYPE_64) }.map_err(
            |result| match result {
                vk::Result::NOT_READY => VkError::Invalid(format!(
                    "timestamps of '{}' not available (was the frame submitted and waited for?)",
                    self.name
                )),
                result => VkError::Call { what: "vkGetQueryPoolResults(method timestamps)", result },
            },
        )?;
        Ok(ts)
    }

    /// Milliseconds from timestamp `from` to timestamp `to`, after the
    /// submission that wrote them has been waited for. Read without
    /// VK_QUERY_RESULT_WAIT_BIT (which could block forever on a timestamp
    /// never submitted): called too early, this is an error instead.
    pub fn elapsed_ms(&self, from: u32, to: u32) -> VkResult<f64> {
        if self.ctx.info.timestamp_valid_bits == 0 {
            return Err(VkError::Unsupported { device: self.ctx.info.name.clone(), what: "timestamp queries on its queue".into() });
        }
        if from >= self.count || to >= self.count {
            return Err(VkError::Invalid(format!("timestamps {from}..{to} of '{}', which holds {}", self.name, self.count)));
        }
        let ts = self.ticks()?;
        let m = self.valid_mask;
        let ticks = (ts[to as usize] & m).wrapping_sub(ts[from as usize] & m) & m;
        Ok(ticks as f64 * self.period_ns * 1e-6)
    }
}

impl TimestampPool {
    /// Milliseconds from timestamp 0 to every timestamp (the first 0), all
    /// read in one query-pool read (`elapsed_ms` reads them all for each
    /// pair: a method timing several passes reads once).
    pub fn all_ms(&self) -> VkResult<Vec<f64>> {
        let ticks = self.ticks()?;
        let m = self.valid_mask;
        let first = ticks.first().map_or(0, |&t| t & m);
        Ok(ticks.iter().map(|&t| ((t & m).wrapping_sub(first) & m) as f64 * self.period_ns * 1e-6).collect())
    }

    /// Milliseconds from timestamp 0 to each later one, once all are
    /// available (`None` before that, or on a queue without timestamps):
    /// for a method that reads its own passes without failing the frame.
    pub fn read(&self) -> Option<Vec<f64>> {
        if self.ctx.info.timestamp_valid_bits == 0 {
            return None;
        }
        (1..self.count).map(|i| self.elapsed_ms(0, i).ok()).collect()
    }
}

impl Drop for TimestampPool {
    fn drop(&mut self) {
        // SAFETY: the owner is being dropped: nothing else holds the handle,
        // no pending submission uses it (owners wait for their recorders before
        // dropping resources: the sync model of `context.rs`), and it is
        // destroyed once, here.
        unsafe { self.ctx.device.destroy_query_pool(self.raw, None) };
    }
}
