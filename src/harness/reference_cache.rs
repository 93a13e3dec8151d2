//! Reference images, computed once per (dataset digest, camera, size,
//! transfer function, reference settings) and cached on disk: the f64 CPU
//! reference takes seconds, and sweeps compare dozens of runs with the same
//! view. It serves every dataset kind: what the reference is comes from the
//! dataset (`Dataset::reference_image`).
//!
//! Nothing read back is trusted. An entry holds its full key text and a
//! SHA-256 of the key and pixels; an entry whose magic, size, key or checksum
//! does not match (a corrupted file, a hash collision of the file name) is
//! recomputed, rewritten and reported (`error.reference_recomputed`). Files
//! live in `VOLBENCH_CACHE` (default `target/volbench-cache/` of this
//! checkout), written all-or-nothing through `fsio`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result};
use sha2::{Digest as _, Sha256};

use super::datasets::{hex, Dataset};
use super::image::RgbaImage;
use crate::scene::{Camera, TransferFunction};

const MAGIC: &[u8; 8] = b"VBREF02\n";

/// A reference image and where it came from.
pub struct Reference {
    pub image: RgbaImage,
    /// Human-readable description recorded as `error.reference`.
    pub what: String,
    /// Time spent computing it (0 when it came from the cache).
    pub compute_ms: f64,
    pub cached: bool,
    /// Why a cache entry that existed was not used (corrupt, other key).
    pub recomputed: Option<String>,
}

pub fn cache_dir() -> PathBuf {
    match std::env::var_os("VOLBENCH_CACHE") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("target").join("volbench-cache"),
    }
}

/// The full key text: everything the reference image depends on.
fn key_text(dataset: &Dataset, tf: &TransferFunction, camera: &Camera, width: u32, height: u32) -> String {
    format!(
        "volbench reference v2\ndataset {} {}\nreference {}\nsize {width}x{height}\ncamera {}\ntf {}\n",
        dataset.kind().name(),
        dataset.digest,
        dataset.reference_description(),
        serde_json::to_string(camera).unwrap_or_default(),
        serde_json::to_string(tf).unwrap_or_default(),
    )
}

fn checksum(key: &[u8], pixels: &[u8]) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update((key.len() as u64).to_le_bytes());
    h.update(key);
    h.update(pixels);
    h.finalize().into()
}

fn pixel_bytes(image: &RgbaImage) -> Vec<u8> {
    image.pixels.iter().flat_map(|p| p.iter().flat_map(|c| c.to_le_bytes())).collect()
}

/// The size of the entry `encode` writes for `key` at `width`x`height`:
/// the read limit, so that every entry written can be read back.
fn entry_bytes(key: &str, width: u32, height: u32) -> u64 {
    (MAGIC.len() + 12 + key.len() + 32) as u64 + 16 * width as u64 * height as u64
}

/// Layout: MAGIC, u32 width, u32 height, u32 key length, key, 32-byte
/// checksum, RGBA f32 pixels (little-endian).
fn encode(key: &str, image: &RgbaImage) -> Vec<u8> {
    let pixels = pixel_bytes(image);
    let mut bytes = Vec::with_capacity(MAGIC.len() + 12 + key.len() + 32 + pixels.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&image.width.to_le_bytes());
    bytes.extend_from_slice(&image.height.to_le_bytes());
    bytes.extend_from_slice(&(key.len() as u32).to_le_bytes());
    bytes.extend_from_slice(key.as_bytes());
    bytes.extend_from_slice(&checksum(key.as_bytes(), &pixels));
    bytes.extend_from_slice(&pixels);
    bytes
}

/// The image stored under `key`, or why the entry cannot be used.
fn decode(bytes: &[u8], key: &str, width: u32, height: u32) -> Result<RgbaImage, String> {
    let u32_at = |o: usize| bytes.get(o..o + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if bytes.get(..8) != Some(MAGIC.as_slice()) {
        return Err("not a volbench reference file (magic)".into());
    }
    let (w, h, klen) = match (u32_at(8), u32_at(12), u32_at(16)) {
        (Some(w), Some(h), Some(k)) => (w, h, k as usize),
        _ => return Err("truncated header".into()),
    };
    if (w, h) != (width, height) {
        return Err(format!("size {w}x{h}, expected {width}x{height}"));
    }
    let key_start = 20;
    let sum_start = key_start + klen;
    let pix_start = sum_start + 32;
    let n = width as usize * height as usize * 16;
    if bytes.len() != pix_start + n {
        return Err(format!("{} bytes, expected {}", bytes.len(), pix_start + n));
    }
    if &bytes[key_start..sum_start] != key.as_bytes() {
        return Err("made for another dataset, view or transfer function (key mismatch)".into());
    }
    let pixels = &bytes[pix_start..];
    if bytes[sum_start..pix_start] != checksum(key.as_bytes(), pixels) {
        return Err("checksum mismatch (corrupted)".into());
    }
    let f = |c: &[u8]| f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    let pixels: Vec<[f32; 4]> = pixels.chunks_exact(16).map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12]), f(&c[12..16])]).collect();
    // A checksum proves the bytes were not damaged, not that whoever wrote
    // them wrote an image: every channel must be finite and in [0, 1]
    // (with room for rounding).
    if let Some(i) = pixels.iter().position(|p| p.iter().any(|c| !(-1e-3..=1.0 + 1e-3).contains(c))) {
        return Err(format!("pixel {i} is {:?}, not a colour in [0, 1] (forged or foreign)", pixels[i]));
    }
    Ok(RgbaImage { width, height, pixels })
}

/// The reference image of `dataset` under `tf` seen by `camera`, from the
/// cache when a valid entry exists. A cache that cannot be written only
/// costs recomputation (a warning says so).
pub fn reference_image(dataset: &Dataset, tf: &TransferFunction, camera: &Camera, width: u32, height: u32) -> Result<Reference> {
    let key = key_text(dataset, tf, camera, width, height);
    let name_hash = hex(&Sha256::digest(key.as_bytes())[..12]);
    let path = cache_dir().join(format!("{}-{}x{}-{name_hash}.ref", sanitize(&dataset.name), width, height));
    let what = format!(
        "{}; dataset {} (sha256 {}), {}x{}, eye {:?}, tf {}",
        dataset.reference_description(),
        dataset.name,
        &dataset.digest[..16.min(dataset.digest.len())],
        width,
        height,
        camera.eye,
        tf.name
    );
    let mut recomputed = None;
    if let Ok(meta) = std::fs::symlink_metadata(&path) {
        // Something is there: use it only if it is a regular file (never a
        // link: the cache reads and replaces its own entries only) holding
        // a valid entry for this key. An unusable one is removed, so that
        // the new entry replaces it and not what a link points to.
        let why = if meta.file_type().is_symlink() {
            "a symbolic link, not an entry the cache wrote".to_string()
        } else {
            match crate::fsio::read_input(&path, "reference cache entry", entry_bytes(&key, width, height)) {
                Ok(bytes) => match decode(&bytes, &key, width, height) {
                    Ok(image) => return Ok(Reference { image, what, compute_ms: 0.0, cached: true, recomputed: None }),
                    Err(why) => why,
                },
                Err(e) => format!("{e:#}"),
            }
        };
        crate::progress!("volbench: reference cache entry {} not used: {why}; recomputing", path.display());
        if !meta.is_dir() {
            let _ = std::fs::remove_file(&path);
        }
        recomputed = Some(why);
    }
    let start = Instant::now();
    let pixels = dataset.reference_image(tf, camera, width, height)?;
    let image = RgbaImage { width, height, pixels };
    let compute_ms = start.elapsed().as_secs_f64() * 1e3;
    let written = std::fs::create_dir_all(cache_dir())
        .with_context(|| format!("creating the cache directory {}", cache_dir().display()))
        .and_then(|()| crate::fsio::write_output(&path, &encode(&key, &image)));
    if let Err(e) = written {
        crate::progress!("volbench: warning: reference cache not written: {e:#}");
    }
    Ok(Reference { image, what, compute_ms, cached: false, recomputed })
}

fn sanitize(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_roundtrip_and_refuse_corruption_other_keys_and_sizes() {
        let img = RgbaImage { width: 2, height: 1, pixels: vec![[0.25, 0.5, 0.75, 1.0], [0.0, 0.1, 0.2, 0.3]] };
        let bytes = encode("key A", &img);
        assert_eq!(decode(&bytes, "key A", 2, 1).unwrap().pixels, img.pixels);
        assert!(decode(&bytes, "key B", 2, 1).unwrap_err().contains("key mismatch"));
        assert!(decode(&bytes, "key A", 1, 2).unwrap_err().contains("size"));
        // One flipped bit in the pixels, length unchanged: refused.
        let mut bad = bytes.clone();
        let last = bad.len() - 3;
        bad[last] ^= 0x10;
        assert!(decode(&bad, "key A", 2, 1).unwrap_err().contains("checksum"));
        assert!(decode(b"garbage", "key A", 2, 1).is_err());
        assert!(decode(&bytes[..bytes.len() - 1], "key A", 2, 1).is_err());
    }

    #[test]
    fn forged_pixels_are_refused_and_the_read_limit_fits_what_is_written() {
        let key = "k".repeat(3 << 20);
        let img = RgbaImage { width: 2, height: 1, pixels: vec![[0.5; 4], [f32::NAN, 0.0, 0.0, 1.0]] };
        let bytes = encode(&key, &img);
        assert!(decode(&bytes, &key, 2, 1).unwrap_err().contains("pixel 1"));
        let img = RgbaImage { width: 2, height: 1, pixels: vec![[0.5; 4], [1.0, 0.0, 0.0, 1.0]] };
        assert_eq!(encode(&key, &img).len() as u64, entry_bytes(&key, 2, 1));
        for px in [[-0.5, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 2.0], [0.0, f32::INFINITY, 0.0, 0.0]] {
            let img = RgbaImage { width: 1, height: 1, pixels: vec![px] };
            assert!(decode(&encode("a", &img), "a", 1, 1).is_err(), "{px:?}");
        }
    }
}
