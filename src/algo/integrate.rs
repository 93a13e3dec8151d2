//! Tables for ray integration on the GPU, built once on the CPU in f64:
//! the transfer function sampled for linear lookup, and the partial
//! pre-integration table Psi(gamma_f, gamma_b) (Moreland & Angel 2004), which
//! depends on nothing but its resolution.

use std::sync::Arc;

use ash::vk as raw;
use rayon::prelude::*;

use crate::scene::TransferFunction;
use crate::vk::{upload_static, Buffer, Context, StorageBufferSet, UploadCounter, VkResult};

/// Default sizes: the TF table resolves control points to 1/1023 of the
/// range; a 512^2 Psi table keeps per-lookup error near 1e-3 or below.
pub const TF_TABLE_SIZE: usize = 1024;
pub const PSI_TABLE_SIZE: usize = 512;

/// tau*D from the table coordinate gamma = tau*D / (tau*D + 1).
fn tau_d(gamma: f64) -> f64 {
    if gamma >= 1.0 {
        f64::INFINITY
    } else {
        gamma / (1.0 - gamma)
    }
}

/// Psi on an `m` x `m` grid over gamma in [0, 1], row = back, column = front.
pub fn psi_table(m: usize) -> Vec<f32> {
    let m = m.max(2);
    let mut out = vec![0f32; m * m];
    out.par_chunks_mut(m).enumerate().for_each(|(jb, row)| {
        let tb = tau_d(jb as f64 / (m - 1) as f64);
        for (jf, v) in row.iter_mut().enumerate() {
            let tf = tau_d(jf as f64 / (m - 1) as f64);
            // Infinite attenuation at either end makes the average
            // transmittance vanish (its limit is 0).
            *v = if tf.is_infinite() || tb.is_infinite() { 0.0 } else { crate::reference::psi::psi(tf, tb) as f32 };
        }
    });
    out
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

/// The integration tables on the device and the descriptor set that binds
/// them (binding 0: transfer function, binding 1: Psi).
pub struct IntegrationTables {
    pub tf_range: (f64, f64),
    pub tf_size: usize,
    pub psi_size: usize,
    pub set: StorageBufferSet,
    _tf: Buffer,
    _psi: Buffer,
    /// CPU time spent building the tables (reported apart from frames).
    pub build_ms: f64,
}

impl IntegrationTables {
    pub fn new(ctx: &Arc<Context>, tf: &TransferFunction, range: (f64, f64), counter: &mut UploadCounter) -> VkResult<Self> {
        let t0 = std::time::Instant::now();
        let (lo, hi) = if range.1 > range.0 { range } else { (range.0, range.0 + 1.0) };
        let tf_table = tf.table(TF_TABLE_SIZE, lo, hi);
        let psi = psi_quads(&psi_table(PSI_TABLE_SIZE), PSI_TABLE_SIZE);
        let build_ms = t0.elapsed().as_secs_f64() * 1e3;
        let usage = raw::BufferUsageFlags::STORAGE_BUFFER;
        let tf_buf = upload_static(ctx, "transfer function table", bytemuck::cast_slice(&tf_table), usage, counter)?;
        let psi_buf = upload_static(ctx, "psi table", bytemuck::cast_slice(&psi), usage, counter)?;
        let set = StorageBufferSet::new(ctx, "integration tables", &[&tf_buf, &psi_buf], raw::ShaderStageFlags::FRAGMENT)?;
        Ok(IntegrationTables { tf_range: (lo, hi), tf_size: TF_TABLE_SIZE, psi_size: PSI_TABLE_SIZE, set, _tf: tf_buf, _psi: psi_buf, build_ms })
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
    fn psi_table_corners() {
        let t = psi_table(65);
        assert!((t[0] - 1.0).abs() < 1e-6, "no attenuation: full transmittance");
        assert_eq!(t[65 * 65 - 1], 0.0);
        // Symmetric constant attenuation on the diagonal: (1 - e^-x) / x.
        let j = 32; // gamma = 0.5 -> tau D = 1
        let v = t[j * 65 + j] as f64;
        assert!((v - (1.0 - (-1f64).exp())).abs() < 1e-6, "{v}");
    }
}
