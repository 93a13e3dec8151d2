//! The suite's figures: bar charts of frame time and bytes per frame by run
//! (PNG and SVG), and a montage of every run's image beside its ×10
//! difference from the f64 reference. Written all-or-nothing via `fsio`.

use std::path::Path;

use anyhow::Result;

use super::image::{write_rgb8_png, RgbaImage};
use super::suite::Summary;

/// One horizontal-bar chart per measure, as `<dir>/<name>.png` and `.svg`.
pub fn bar_charts(dir: &Path, s: &Summary) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    super::pareto::register_font()?;
    let rows: Vec<(String, f64, f64)> = s
        .runs
        .iter()
        .filter_map(|r| {
            let x = r.result.as_ref()?;
            Some((format!("{} / {}", r.dataset, r.label), x.time_ms.phase("frame").median, x.upload.bytes_per_frame as f64 / 1e6))
        })
        .collect();
    if rows.is_empty() {
        return Ok(());
    }
    let device = &s.environment.device.name;
    // Peers (`--peers`) have frame times but no byte counts.
    let peers: Vec<(String, f64)> = s
        .peers
        .iter()
        .filter_map(|p| Some((format!("{} / peer {}/{}", p.dataset, p.peer, p.renderer), p.frame_ms?.median)))
        .collect();
    let times: Vec<(String, f64)> = rows.iter().map(|r| (r.0.clone(), r.1)).chain(peers).collect();
    let bytes: Vec<(String, f64)> = rows.iter().map(|r| (r.0.clone(), r.2)).collect();
    for (name, title, chart) in [
        ("frame_time", format!("median frame time (ms), {}x{}, {device}", s.settings.width, s.settings.height), &times),
        ("bytes_per_frame", "bytes crossing to the device per frame (MB)".to_string(), &bytes),
    ] {
        let labels: Vec<&str> = chart.iter().map(|r| r.0.as_str()).collect();
        let values: Vec<f64> = chart.iter().map(|r| r.1).collect();
        let (w, h) = (1000u32, 120 + 40 * chart.len() as u32);
        let mut rgb = vec![0u8; (w * h * 3) as usize];
        {
            let root = plotters::prelude::BitMapBackend::with_buffer(&mut rgb, (w, h));
            draw_bars(root, &title, &labels, &values)?;
        }
        write_rgb8_png(&dir.join(format!("{name}.png")), w, h, &rgb)?;
        let mut svg = String::new();
        {
            let root = plotters::prelude::SVGBackend::with_string(&mut svg, (w, h));
            draw_bars(root, &title, &labels, &values)?;
        }
        crate::fsio::write_output(&dir.join(format!("{name}.svg")), svg.as_bytes())?;
    }
    Ok(())
}

fn draw_bars<B: plotters::prelude::DrawingBackend>(backend: B, title: &str, labels: &[&str], values: &[f64]) -> Result<()> {
    use plotters::prelude::*;
    let root = backend.into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let max = values.iter().copied().fold(0.0, f64::max).max(1e-9) * 1.15;
        let n = labels.len() as i32;
        // One segment per run: labels at the segments' centres.
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(35)
            .y_label_area_size(260)
            .build_cartesian_2d(0.0..max, (0..n).into_segmented())
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(labels.len())
            .y_label_formatter(&|y| match y {
                SegmentValue::CenterOf(i) => labels.get(*i as usize).map(|l| l.to_string()).unwrap_or_default(),
                _ => String::new(),
            })
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(values.iter().enumerate().map(|(i, &v)| {
                let i = i as i32;
                Rectangle::new([(0.0, SegmentValue::Exact(i)), (v, SegmentValue::Exact(i + 1))], RGBColor(40, 90, 200).filled())
            }))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(values.iter().enumerate().map(|(i, &v)| {
                Text::new(format!(" {v:.1}"), (v, SegmentValue::CenterOf(i as i32)), ("sans-serif", 13).into_font())
            }))
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("drawing '{title}': {e}"))
}

/// Every image and its difference side by side, one row per run, captioned.
pub fn montage(path: &Path, images: &[(String, RgbaImage, Option<RgbaImage>)]) -> Result<()> {
    use plotters::prelude::*;
    super::pareto::register_font()?;
    let tile = 256u32;
    let caption = 24u32;
    let (w, h) = (2 * tile, images.len() as u32 * (tile + caption));
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("montage: {e}"))?;
        for (row, (label, image, diff)) in images.iter().enumerate() {
            let y0 = row as u32 * (tile + caption);
            root.draw(&Text::new(label.clone(), (6, y0 as i32 + 4), ("sans-serif", 15).into_font()))
                .map_err(|e| anyhow::anyhow!("montage: {e}"))?;
            for (col, img) in [Some(image), diff.as_ref()].into_iter().enumerate() {
                let Some(img) = img else { continue };
                for ty in 0..tile {
                    for tx in 0..tile {
                        let sx = (tx as u64 * img.width as u64 / tile as u64) as usize;
                        let sy = (ty as u64 * img.height as u64 / tile as u64) as usize;
                        let p = img.pixels[sy * img.width as usize + sx];
                        let c = |v: f32| if v.is_finite() { (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8 } else { 255 };
                        let _ = root.draw_pixel(((col as u32 * tile + tx) as i32, (y0 + caption + ty) as i32), &RGBColor(c(p[0]), c(p[1]), c(p[2])));
                    }
                }
            }
        }
        root.present().map_err(|e| anyhow::anyhow!("montage: {e}"))?;
    }
    write_rgb8_png(path, w, h, &rgb)
}
