//! Reference images, computed once per (mesh, camera, size, transfer
//! function) and cached on disk: the f64 CPU reference takes seconds, and
//! sweeps compare dozens of runs with the same view.
//!
//! The key hashes everything the image depends on: the mesh's points,
//! scalars and cells, the camera, the size and the transfer function. Files
//! live in `VOLBENCH_CACHE` (default `target/volbench-cache/` of this
//! checkout) as a small header plus RGBA f32, written atomically.

use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result};

use super::image::RgbaImage;
use super::run::Scene;
use crate::scene::Camera;

const MAGIC: &[u8; 8] = b"VBREF01\n";

/// A reference image and where it came from.
pub struct Reference {
    pub image: RgbaImage,
    /// Human-readable description recorded as `error.reference`.
    pub what: String,
    /// Time spent computing it (0 when it came from the cache).
    pub compute_ms: f64,
    pub cached: bool,
}

pub fn cache_dir() -> PathBuf {
    match std::env::var_os("VOLBENCH_CACHE") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("target").join("volbench-cache"),
    }
}

fn key(scene: &Scene, camera: &Camera, width: u32, height: u32) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    "volbench reference v1".hash(&mut h);
    for p in &scene.mesh.points {
        p.map(f64::to_bits).hash(&mut h);
    }
    for s in &scene.mesh.scalars {
        s.to_bits().hash(&mut h);
    }
    scene.mesh.tets.hash(&mut h);
    serde_json::to_string(camera).unwrap_or_default().hash(&mut h);
    serde_json::to_string(scene.tf).unwrap_or_default().hash(&mut h);
    (width, height).hash(&mut h);
    h.finish()
}

fn read(path: &Path, width: u32, height: u32) -> Option<RgbaImage> {
    let bytes = std::fs::read(path).ok()?;
    let n = width as usize * height as usize * 16;
    if bytes.len() != MAGIC.len() + 8 + n || &bytes[..8] != MAGIC {
        return None;
    }
    let w = u32::from_le_bytes(bytes[8..12].try_into().ok()?);
    let h = u32::from_le_bytes(bytes[12..16].try_into().ok()?);
    if (w, h) != (width, height) {
        return None;
    }
    let f = |c: &[u8]| f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    let pixels = bytes[16..].chunks_exact(16).map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12]), f(&c[12..16])]).collect();
    Some(RgbaImage { width, height, pixels })
}

fn write(path: &Path, image: &RgbaImage) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut bytes = Vec::with_capacity(16 + image.pixels.len() * 16);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&image.width.to_le_bytes());
    bytes.extend_from_slice(&image.height.to_le_bytes());
    for p in &image.pixels {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    crate::fsio::write_output(path, &bytes)
}

/// The f64 reference image of `scene` seen by `camera`, from the cache when
/// possible. A cache that cannot be written only costs recomputation.
pub fn reference_image(scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<Reference> {
    let k = key(scene, camera, width, height);
    let path = cache_dir().join(format!("{}-{}x{}-{:016x}.ref", scene.mesh.name, width, height, k));
    let what = format!(
        "f64 CPU ray walk, exact emission-absorption; mesh {}, {}x{}, eye {:?}, tf {} (key {:016x})",
        scene.mesh.name, width, height, camera.eye, scene.tf.name, k
    );
    if let Some(image) = read(&path, width, height) {
        return Ok(Reference { image, what, compute_ms: 0.0, cached: true });
    }
    let start = Instant::now();
    let r = crate::reference::render_reference(scene.mesh, camera, scene.tf, width, height)
        .with_context(|| format!("rendering the f64 reference of '{}'", scene.mesh.name))?;
    let image = RgbaImage { width, height, pixels: r.pixels.iter().map(|p| p.map(|c| c as f32)).collect() };
    let compute_ms = start.elapsed().as_secs_f64() * 1e3;
    if let Err(e) = write(&path, &image) {
        eprintln!("volbench: warning: reference cache not written: {e:#}");
    }
    Ok(Reference { image, what, compute_ms, cached: false })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_roundtrip_and_rejects_wrong_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.ref");
        let img = RgbaImage { width: 2, height: 1, pixels: vec![[0.25, 0.5, 0.75, 1.0], [0.0, 0.1, 0.2, 0.3]] };
        write(&p, &img).unwrap();
        let back = read(&p, 2, 1).unwrap();
        assert_eq!(back.pixels, img.pixels);
        assert!(read(&p, 1, 2).is_none());
        std::fs::write(&p, b"garbage").unwrap();
        assert!(read(&p, 2, 1).is_none());
    }
}
