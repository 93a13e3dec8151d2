//! Ray integration on the GPU: which integrator the fragment stage compiles
//! in (a build-time parameter, `shaders/common/integrate.glsl`) and the tables
//! it reads, built once on the CPU in f64 (with the method side's own Ψ and
//! segment integral, `algo::psi` and `algo::segment`, not the CPU
//! reference's): the transfer function sampled for
//! linear lookup, plus per integrator the partial pre-integration table
//! Psi(gamma_f, gamma_b) (Moreland & Angel 2004; independent of the transfer
//! function) or the classic pre-integration table over (s_f, s_b, D) (rebuilt
//! whenever the transfer function changes).

use std::sync::Arc;

use rayon::prelude::*;

use crate::scene::TransferFunction;
use crate::vk::{upload_static_texels, BufferUsage, Context, DescriptorKind, DescriptorResource, DescriptorSet, DescriptorSetDesc, TexelBuffer, UploadCounter};
use crate::vk::{Format, Stages};

/// Default sizes: the TF table resolves control points to 1/1023 of the
/// range; a 512^2 Psi table keeps per-lookup error near 1e-3 or below.
pub const TF_TABLE_SIZE: usize = 1024;
pub const PSI_TABLE_SIZE: usize = 512;
/// Classic pre-integration: scalar samples per axis (the length axis has a
/// quarter as many).
pub const PREINT_TABLE_SIZE: usize = 128;

/// Largest integration table built: 256 MiB on the device (the host holds
/// as much again while building and staging it). The defaults take 4 MiB
/// (ppi, 512) and 8 MiB (preint, 128); the largest accepted sides are 4097
/// for ppi and 407 for preint. Without the bound `--table-size 2048` made
/// preint abort on a failed allocation of hundreds of GB, and 512 took
/// 1.65 GB.
pub const MAX_TABLE_BYTES: u64 = 256 << 20;

/// Bytes of the table `integrator` uploads for a table side of `size`
/// (already defaulted and clamped as `IntegrationTables::new` does), with
/// how it is made up; `None` if it does not even fit in u128.
fn table_bytes(integrator: Integrator, size: usize) -> Option<(u128, String)> {
    let n = size as u128;
    match integrator {
        // (m-1)^2 cells of 4 corner values (`psi_quads`).
        Integrator::Ppi => {
            let cells = (n - 1).checked_mul(n - 1)?;
            Some((cells.checked_mul(16)?, format!("{} x {} cells x 16 bytes", n - 1, n - 1)))
        }
        // n x n scalar pairs x n/4 lengths of RGBA f32 (`preint_table`).
        Integrator::Preint => {
            let nd = (n / 4).max(2);
            let bytes = n.checked_mul(n)?.checked_mul(nd)?.checked_mul(16)?;
            Some((bytes, format!("{n} x {n} scalar pairs x {nd} lengths x 16 bytes")))
        }
        // A one-entry placeholder.
        Integrator::Average | Integrator::LinearExact => Some((16, "no table".into())),
    }
}

/// The table side `IntegrationTables::new` builds for `table_size` (0: the
/// integrator's default).
fn table_side(integrator: Integrator, table_size: usize) -> usize {
    if table_size == 0 {
        integrator.default_table_size()
    } else {
        table_size.max(2)
    }
}

/// Refuses a `--table-size` whose table would take more than
/// [`MAX_TABLE_BYTES`], before anything is allocated (checked arithmetic:
/// any `usize` gives an answer). `table_size` 0 means the integrator's
/// default. Called by every table builder here, so no path bypasses it.
pub fn check_table_size(integrator: Integrator, table_size: usize) -> anyhow::Result<()> {
    check_table_size_within(integrator, table_size, MAX_TABLE_BYTES, "volbench's table limit")
}

/// [`check_table_size`] against `limit` bytes (`why` names the limit, e.g.
/// the device's storage-buffer range).
pub fn check_table_size_within(integrator: Integrator, table_size: usize, limit: u64, why: &str) -> anyhow::Result<()> {
    let side = table_side(integrator, table_size);
    let fits = |s: usize| table_bytes(integrator, s).is_some_and(|(b, _)| b <= limit as u128);
    if fits(side) {
        return Ok(());
    }
    // The largest side that fits (sizes grow with the side): for the message.
    let (mut ok, mut too_big) = (2usize, side);
    while too_big - ok > 1 {
        let mid = ok + (too_big - ok) / 2;
        if fits(mid) {
            ok = mid;
        } else {
            too_big = mid;
        }
    }
    let implied = match table_bytes(integrator, side) {
        Some((bytes, how)) => format!("{bytes} bytes ({:.1} MiB: {how})", bytes as f64 / (1u64 << 20) as f64),
        None => "more bytes than 2^128".to_string(),
    };
    anyhow::bail!(
        "--table-size {table_size} for {}: the table would take {implied}, more than {why} of \
         {limit} bytes ({} MiB); the largest accepted --table-size for {} here is {ok}",
        integrator.name(),
        limit >> 20,
        integrator.name()
    )
}

crate::choices! {
    /// How the fragment stage integrates a segment.
    #[derive(Default)]
    pub enum Integrator {
        /// Average colour and attenuation (Shirley-Tuchman style): fast, colour bleeding.
        Average = "average",
        /// Classic pre-integration: a table over (front scalar, back scalar, length).
        Preint = "preint",
        /// Partial pre-integration (Moreland & Angel): a Psi table over gamma.
        #[default]
        Ppi = "ppi",
        /// Linear colour and attenuation, Psi in closed form (erf, Dawson).
        LinearExact = "linear-exact",
    }
}

impl Integrator {

    /// The shader define selecting it (`ppi` is the default branch).
    pub fn define(self) -> Option<(&'static str, &'static str)> {
        match self {
            Integrator::Average => Some(("INTEGRATOR_AVERAGE", "1")),
            Integrator::Preint => Some(("INTEGRATOR_PREINT", "1")),
            Integrator::Ppi => None,
            Integrator::LinearExact => Some(("INTEGRATOR_LINEAR_EXACT", "1")),
        }
    }

    /// The table side used when none is asked for (0: no table).
    pub fn default_table_size(self) -> usize {
        match self {
            Integrator::Preint => PREINT_TABLE_SIZE,
            Integrator::Ppi => PSI_TABLE_SIZE,
            Integrator::Average | Integrator::LinearExact => 0,
        }
    }
}

/// Classic pre-integration table: for front scalar index f, back scalar
/// index b (`n` samples over `range` each) and length index d (`n / 4`
/// samples of x = D / (D + length_scale) over [0, 1]) the exact integral of
/// the transfer function's segment in f64, premultiplied RGBA, laid out
/// [d][b][f].
pub fn preint_table(
    tf: &TransferFunction,
    range: (f64, f64),
    n: usize,
    length_scale: f64,
) -> anyhow::Result<Vec<[f32; 4]>> {
    check_table_size(Integrator::Preint, n)?;
    let n = n.max(2);
    let nd = (n / 4).max(2);
    let mut out = vec![[0f32; 4]; n * n * nd];
    out.par_chunks_mut(n * n).enumerate().for_each(|(d, slab)| {
        let x = d as f64 / (nd - 1) as f64;
        // x = 1 stands for an infinitely long segment.
        let len = if x >= 1.0 { 1e6 * length_scale } else { length_scale * x / (1.0 - x) };
        for b in 0..n {
            let sb = range.0 + (range.1 - range.0) * b as f64 / (n - 1) as f64;
            for f in 0..n {
                let sf = range.0 + (range.1 - range.0) * f as f64 / (n - 1) as f64;
                let seg = super::segment::integrate_segment(tf, sf, sb, len);
                slab[b * n + f] = seg.rgba().map(|v| v as f32);
            }
        }
    });
    Ok(out)
}

/// tau*D from the table coordinate gamma = tau*D / (tau*D + 1).
fn tau_d(gamma: f64) -> f64 {
    if gamma >= 1.0 {
        f64::INFINITY
    } else {
        gamma / (1.0 - gamma)
    }
}

/// Psi on an `m` x `m` grid over gamma in [0, 1], row = back, column = front.
pub fn psi_table(m: usize) -> anyhow::Result<Vec<f32>> {
    check_table_size(Integrator::Ppi, m)?;
    let m = m.max(2);
    let mut out = vec![0f32; m * m];
    out.par_chunks_mut(m).enumerate().for_each(|(jb, row)| {
        let tb = tau_d(jb as f64 / (m - 1) as f64);
        for (jf, v) in row.iter_mut().enumerate() {
            let tf = tau_d(jf as f64 / (m - 1) as f64);
            // Infinite attenuation at either end makes the average
            // transmittance vanish (its limit is 0).
            *v = if tf.is_infinite() || tb.is_infinite() { 0.0 } else { super::psi::psi(tf, tb) as f32 };
        }
    });
    Ok(out)
}

/// The Psi table as the shader reads it: for each of the (m-1)^2 grid cells
/// the values at its 4 corners (f0b0, f1b0, f0b1, f1b1) in one vec4, so that a
/// bilinear lookup is one load instead of four (loads are gathers on a
/// software rasterizer, the most expensive part of the lookup).
pub fn psi_quads(table: &[f32], m: usize) -> Vec<[f32; 4]> {
    let mut out = Vec::with_capacity((m - 1) * (m - 1));
    for jb in 0..m - 1 {
        for jf in 0..m - 1 {
            let at = |b: usize, f: usize| table[b * m + f];
            out.push([at(jb, jf), at(jb, jf + 1), at(jb + 1, jf), at(jb + 1, jf + 1)]);
        }
    }
    out
}

/// The Psi corner quads at side `m`, built once per size per process (the
/// table does not depend on the transfer function; the stress suite and
/// sweeps would otherwise rebuild it for every run).
pub fn psi_quads_cached(m: usize) -> anyhow::Result<Arc<Vec<[f32; 4]>>> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Tables = Mutex<HashMap<usize, Arc<Vec<[f32; 4]>>>>;
    static CACHE: OnceLock<Tables> = OnceLock::new();
    let cache = CACHE.get_or_init(Default::default);
    if let Some(t) = cache.lock().ok().and_then(|c| c.get(&m).cloned()) {
        return Ok(t);
    }
    let t = Arc::new(psi_quads(&psi_table(m)?, m));
    if let Ok(mut c) = cache.lock() {
        c.insert(m, t.clone());
    }
    Ok(t)
}

/// How a segment's scalars and length index the tables
/// (`shaders/common/table_map.glsl`, read by `common/integrate.glsl`): a
/// member of the push constants of every shader that integrates cells
/// (`tet_mesh::FrameConstants`, `tet_raycast::WalkFrame`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TableMap {
    /// The lowest tabulated scalar, mapped as the cells' scalars are.
    pub tf_lo: f32,
    /// 1 / (highest - lowest), mapped alike.
    pub tf_inv_range: f32,
    /// Entries of the transfer-function table.
    pub tf_entries: f32,
    /// Side of the integration table.
    pub table_side: f32,
    /// Length scale of the pre-integration table's length axis.
    pub preint_length: f32,
}

/// The integration tables on the device and the descriptor set that binds
/// them (binding 0: transfer function, binding 1: the integrator's table).
pub struct IntegrationTables {
    pub integrator: Integrator,
    pub tf_range: (f64, f64),
    pub tf_size: usize,
    /// Side of the integrator's table (0 when it has none).
    pub table_size: usize,
    /// Length scale of the pre-integration table's length axis.
    pub length_scale: f64,
    pub set: DescriptorSet,
    _tf: TexelBuffer,
    _table: TexelBuffer,
    /// CPU time spent building the tables (reported apart from frames).
    pub build_ms: f64,
}

impl IntegrationTables {
    /// The tables' [`TableMap`] for scalars sent as (s - `scalar_origin`)
    /// / `scalar_scale` (`cell_projection::scalar_map`).
    pub fn map(&self, scalar_origin: f64, scalar_scale: f64) -> TableMap {
        let (lo, hi) = self.tf_range;
        TableMap {
            tf_lo: ((lo - scalar_origin) / scalar_scale) as f32,
            tf_inv_range: (scalar_scale / (hi - lo)) as f32,
            tf_entries: self.tf_size as f32,
            table_side: self.table_size as f32,
            preint_length: self.length_scale as f32,
        }
    }

    /// `table_size` 0 picks the integrator's default; `length_scale` is a
    /// typical cell size (the pre-integration table's length axis is
    /// D / (D + length_scale)). Refuses a table larger than
    /// [`MAX_TABLE_BYTES`] before allocating anything.
    pub fn new(
        ctx: &Arc<Context>,
        tf: &TransferFunction,
        range: (f64, f64),
        integrator: Integrator,
        table_size: usize,
        length_scale: f64,
        counter: &mut UploadCounter,
    ) -> anyhow::Result<Self> {
        Self::for_stages(ctx, tf, range, integrator, table_size, length_scale, Stages::FRAGMENT, counter)
    }

    /// [`Self::new`] with the tables visible to `stages` (a compute method
    /// integrates in its compute stage).
    #[allow(clippy::too_many_arguments)]
    pub fn for_stages(
        ctx: &Arc<Context>,
        tf: &TransferFunction,
        range: (f64, f64),
        integrator: Integrator,
        table_size: usize,
        length_scale: f64,
        stages: Stages,
        counter: &mut UploadCounter,
    ) -> anyhow::Result<Self> {
        check_table_size(integrator, table_size)?;
        // The table is one texel buffer of RGBA32F: it must fit the device's
        // element limit.
        let texel_limit = u64::from(ctx.info.max_texel_buffer_elements).saturating_mul(16);
        check_table_size_within(integrator, table_size, texel_limit, "the device's texel-buffer limit (maxTexelBufferElements x 16 bytes)")?;
        let t0 = std::time::Instant::now();
        let (lo, hi) = if range.1 > range.0 { range } else { (range.0, range.0 + 1.0) };
        let tf_table = tf.table(TF_TABLE_SIZE, lo, hi);
        let size = table_side(integrator, table_size);
        let table: Arc<Vec<[f32; 4]>> = match integrator {
            Integrator::Ppi => psi_quads_cached(size)?,
            Integrator::Preint => Arc::new(preint_table(tf, (lo, hi), size, length_scale)?),
            // No table: bind a placeholder so every variant has one layout.
            Integrator::Average | Integrator::LinearExact => Arc::new(vec![[0.0; 4]]),
        };
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        // Texel buffers: a lookup is one texel load. As storage buffers each
        // of a fragment's five vec4 lookups was, on llvmpipe, a per-lane loop
        // of guarded scalar loads per component, about half of balanced's
        // frame on the oxygen post (README: the balanced method at its speed
        // limit). Read as storage texel buffers (`imageBuffer`, imageLoad),
        // not uniform ones (texelFetch): llvmpipe (Mesa 22.3) makes a
        // texelFetch from a float or 32-bit-integer format a call to a
        // sampling function, around which the caller spills every live
        // vector register, and inlines an imageLoad (tet-raycast's walk:
        // counted device instructions -6 %, docs/compute-speed.md).
        let texels = |name: &str, data: &[[f32; 4]], counter: &mut UploadCounter| {
            upload_static_texels(ctx, name, bytemuck::cast_slice(data), Format::Rgba32Float, BufferUsage::STORAGE_TEXEL, counter)
        };
        let tf_buf = texels("transfer function table", &tf_table, counter)?;
        let table_buf = texels("integration table", table.as_slice(), counter)?;
        let desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageTexelBuffer, stages), (DescriptorKind::StorageTexelBuffer, stages)]);
        let set = DescriptorSet::new(
            ctx,
            "integration tables",
            &desc,
            &[DescriptorResource::StorageTexelBuffer(&tf_buf), DescriptorResource::StorageTexelBuffer(&table_buf)],
        )?;
        Ok(IntegrationTables {
            integrator,
            tf_range: (lo, hi),
            tf_size: TF_TABLE_SIZE,
            table_size: size,
            length_scale,
            set,
            _tf: tf_buf,
            _table: table_buf,
            build_ms,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psi_quads_hold_each_cells_corners() {
        let m = 5;
        let table: Vec<f32> = (0..m * m).map(|v| v as f32).collect();
        let q = psi_quads(&table, m);
        assert_eq!(q.len(), (m - 1) * (m - 1));
        // cell (back 2, front 1): corners (2,1), (2,2), (3,1), (3,2)
        assert_eq!(q[2 * (m - 1) + 1], [11.0, 12.0, 16.0, 17.0]);
    }

    #[test]
    fn table_sizes_are_checked_before_allocating() {
        // Defaults and the sizes the pareto sweep uses fit.
        for (i, n) in [(Integrator::Ppi, 0), (Integrator::Ppi, 1024), (Integrator::Ppi, 4097), (Integrator::Preint, 0)] {
            check_table_size(i, n).unwrap_or_else(|e| panic!("{e}"));
        }
        check_table_size(Integrator::Preint, 128).unwrap();
        check_table_size(Integrator::Preint, 407).unwrap();
        // No table: any size is harmless.
        check_table_size(Integrator::Average, usize::MAX).unwrap();
        check_table_size(Integrator::LinearExact, usize::MAX).unwrap();
        // 512 x 512 x 128 x 16 bytes = 512 MiB; 2048 -> 32 GiB.
        let e = check_table_size(Integrator::Preint, 512).unwrap_err().to_string();
        assert!(
            e.contains("--table-size 512 for preint")
                && e.contains("536870912 bytes (512.0 MiB: 512 x 512 scalar pairs x 128 lengths x 16 bytes)")
                && e.contains("table limit of 268435456 bytes (256 MiB)")
                && e.contains("largest accepted --table-size for preint here is 407"),
            "{e}"
        );
        let e = check_table_size(Integrator::Preint, 2048).unwrap_err().to_string();
        assert!(e.contains("34359738368 bytes"), "{e}");
        let e = check_table_size(Integrator::Ppi, 4098).unwrap_err().to_string();
        assert!(e.contains("--table-size 4098 for ppi") && e.contains("is 4097"), "{e}");
        // Absurd sizes: an error, not an overflow.
        let e = check_table_size(Integrator::Preint, usize::MAX).unwrap_err().to_string();
        assert!(e.contains("more bytes than 2^128") && e.contains("is 407"), "{e}");
        let e = check_table_size(Integrator::Ppi, usize::MAX).unwrap_err().to_string();
        assert!(e.contains(&format!("--table-size {}", usize::MAX)), "{e}");
        // The builders refuse too (no allocation happens first).
        assert!(psi_table(1 << 20).is_err());
        let tf = TransferFunction::constant([1.0; 3], 1.0);
        assert!(preint_table(&tf, (0.0, 1.0), 1 << 12, 1.0).is_err());
    }

    #[test]
    fn psi_table_corners() {
        let t = psi_table(65).unwrap();
        assert!((t[0] - 1.0).abs() < 1e-6, "no attenuation: full transmittance");
        assert_eq!(t[65 * 65 - 1], 0.0);
        // Symmetric constant attenuation on the diagonal: (1 - e^-x) / x.
        let j = 32; // gamma = 0.5 -> tau D = 1
        let v = t[j * 65 + j] as f64;
        assert!((v - (1.0 - (-1f64).exp())).abs() < 1e-6, "{v}");
    }
}
