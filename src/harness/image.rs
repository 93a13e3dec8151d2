//! Images as the harness sees them: premultiplied RGBA f32, row 0 at the top.
//! PNG output (composited over black) and image comparison.

use std::path::Path;

use anyhow::{Context as _, Result};
use serde::Serialize;

#[derive(Debug, Clone)]
pub struct RgbaImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

/// Image differences over all four channels.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ImageError {
    pub rmse: f64,
    pub max_abs: f64,
    pub psnr_db: f64,
}

impl RgbaImage {
    /// Pixels with any coverage (alpha > 0).
    pub fn covered_pixels(&self) -> usize {
        self.pixels.iter().filter(|p| p[3] > 0.0).count()
    }

    pub fn non_finite_pixels(&self) -> usize {
        self.pixels.iter().filter(|p| p.iter().any(|c| !c.is_finite())).count()
    }

    /// RMSE, max |difference| and PSNR over RGBA with values clamped to [0, 1].
    pub fn compare(&self, other: &RgbaImage) -> Result<ImageError> {
        self.compare_excluding(other, &[])
    }

    /// [`Self::compare`] with the pixels marked in `exclude` (indexed like
    /// `pixels`; shorter: the rest count) left out of the max |difference|
    /// only: RMSE and PSNR still cover every pixel.
    pub fn compare_excluding(&self, other: &RgbaImage, exclude: &[bool]) -> Result<ImageError> {
        anyhow::ensure!(
            self.width == other.width && self.height == other.height,
            "cannot compare a {}x{} image with a {}x{} one",
            self.width,
            self.height,
            other.width,
            other.height
        );
        let (mut sum, mut max) = (0f64, 0f64);
        for (i, (a, b)) in self.pixels.iter().zip(&other.pixels).enumerate() {
            let counted = !exclude.get(i).copied().unwrap_or(false);
            for c in 0..4 {
                let d = (a[c].clamp(0.0, 1.0) as f64 - b[c].clamp(0.0, 1.0) as f64).abs();
                sum += d * d;
                if counted {
                    max = max.max(d);
                }
            }
        }
        let n = (self.pixels.len() * 4).max(1) as f64;
        let rmse = (sum / n).sqrt();
        let psnr_db = if rmse > 0.0 { -20.0 * rmse.log10() } else { f64::INFINITY };
        Ok(ImageError { rmse, max_abs: max, psnr_db })
    }

    /// |self - other| per channel, amplified 10x, as an image (alpha = 1).
    pub fn difference(&self, other: &RgbaImage) -> RgbaImage {
        let pixels = self
            .pixels
            .iter()
            .zip(&other.pixels)
            .map(|(a, b)| {
                let d = |c: usize| (10.0 * (a[c] - b[c]).abs()).min(1.0);
                let alpha = d(3);
                [d(0).max(alpha), d(1).max(alpha), d(2).max(alpha), 1.0]
            })
            .collect();
        RgbaImage { width: self.width, height: self.height, pixels }
    }

    /// Write an 8-bit RGB PNG: the premultiplied colour over a black
    /// background. Written all-or-nothing (`fsio::write_output`).
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let bytes = self.png_bytes().with_context(|| format!("encoding PNG {}", path.display()))?;
        crate::fsio::write_output(path, &bytes)
    }

    /// The PNG file `write_png` writes, in memory (for `fsio::write_all`).
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        encode_rgb8_png(&mut out, self.width, self.height, &self.rgb8())?;
        Ok(out)
    }

    fn rgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| [p[0], p[1], p[2]])
            .map(|c| if c.is_finite() { (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8 } else { 255 })
            .collect()
    }
}

/// Write 8-bit RGB rows as a PNG, all-or-nothing (`fsio::write_output`).
pub fn write_rgb8_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    crate::fsio::write_output_with(path, |out| encode_rgb8_png(out, width, height, rgb))
        .with_context(|| format!("writing PNG {}", path.display()))
}

fn encode_rgb8_png(out: &mut dyn std::io::Write, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    w.write_image_data(rgb)?;
    w.finish()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excluded_pixels_leave_the_max_but_not_the_rmse() {
        let a = RgbaImage { width: 2, height: 1, pixels: vec![[0.0; 4], [0.0; 4]] };
        let b = RgbaImage { width: 2, height: 1, pixels: vec![[0.1, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0]] };
        let all = a.compare(&b).unwrap();
        let kept = a.compare_excluding(&b, &[false, true]).unwrap();
        assert!((all.max_abs - 0.5).abs() < 1e-6 && (kept.max_abs - 0.1).abs() < 1e-6);
        assert_eq!(all.rmse, kept.rmse);
    }

    #[test]
    fn compare_counts_all_channels() {
        let a = RgbaImage { width: 1, height: 2, pixels: vec![[0.0; 4], [1.0, 0.0, 0.0, 1.0]] };
        let b = RgbaImage { width: 1, height: 2, pixels: vec![[0.0; 4], [0.0, 0.0, 0.0, 1.0]] };
        let e = a.compare(&b).unwrap();
        assert!((e.rmse - (1.0f64 / 8.0).sqrt()).abs() < 1e-12);
        assert_eq!(e.max_abs, 1.0);
        assert_eq!(a.covered_pixels(), 1);
    }

    #[test]
    fn png_roundtrip_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.png");
        let img = RgbaImage { width: 3, height: 2, pixels: vec![[0.5, 0.2, 0.1, 1.0]; 6] };
        img.write_png(&p).unwrap();
        let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&p).unwrap()));
        let reader = dec.read_info().unwrap();
        assert_eq!((reader.info().width, reader.info().height), (3, 2));
        assert!(!dir.path().join("x.png.tmp").exists());
    }
}
