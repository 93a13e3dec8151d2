//! The pipelines of every method, built through one process-wide
//! `vk::PipelineCache` per Vulkan context: a pipeline is described by its
//! `PipelineKey` (shaders, defines, fixed-function state, set layouts) and
//! built once; runs with the same build-time options (every stress case,
//! every sweep row) share it. Methods record `key.id()` in their results so
//! a figure can be traced to the exact pipeline that produced it.

use std::sync::{Arc, Mutex, OnceLock};

use crate::vk::{Context, Pipeline, PipelineCache, PipelineKey, VkResult};

/// One cache per context (keyed by the context's address; a cache holds its
/// context alive, so an address is never reused while its entry exists).
type Caches = Mutex<Vec<(usize, Arc<PipelineCache>)>>;

fn cache(ctx: &Arc<Context>) -> VkResult<Arc<PipelineCache>> {
    static CACHES: OnceLock<Caches> = OnceLock::new();
    let caches = CACHES.get_or_init(Default::default);
    let mut list = caches.lock().unwrap_or_else(|p| p.into_inner());
    let id = Arc::as_ptr(ctx) as usize;
    if let Some((_, c)) = list.iter().find(|(k, _)| *k == id) {
        return Ok(c.clone());
    }
    let c = Arc::new(PipelineCache::new(ctx, crate::shaders::source)?);
    list.push((id, c.clone()));
    Ok(c)
}

/// The pipeline for `key` on `ctx`, built on first use.
pub fn get(ctx: &Arc<Context>, key: &PipelineKey) -> VkResult<Arc<Pipeline>> {
    cache(ctx)?.get(key)
}
