//! Figures: bar charts with a min–max spread (PNG and SVG), a montage grid
//! of images beside their ×10 difference from the f64 reference, and a
//! time-against-error scatter with the Pareto front joined. The callers
//! (`suite`, `pareto`) hand over plain rows; nothing here knows a result
//! record. Written all-or-nothing via `fsio`.

use std::path::Path;

use anyhow::Result;
use plotters::style::RGBColor;

use super::image::{write_rgb8_png, RgbaImage};

const FONT_PATHS: [&str; 2] =
    ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/dejavu/DejaVuSans.ttf"];

/// Register a TrueType font for plot labels (plotters is built with
/// `ab_glyph`, which has no system font lookup; criterion's plots need it
/// too). Idempotent.
pub fn register_font() -> Result<()> {
    use std::sync::OnceLock;
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        FONT_PATHS.iter().any(|p| {
            std::fs::read(p)
                .ok()
                .map(|bytes| {
                    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes).is_ok()
                })
                .unwrap_or(false)
        })
    });
    anyhow::ensure!(ok, "no font for plot labels: install fonts-dejavu-core (scripts/setup.sh does), looked in {FONT_PATHS:?}");
    Ok(())
}

/// Colours told apart at a glance (Okabe–Ito, then darker shades).
const PALETTE: [RGBColor; 10] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 60, 160),
    RGBColor(150, 110, 40),
    RGBColor(60, 60, 60),
    RGBColor(200, 40, 40),
];

/// The peers' colour in bar charts (volbench's runs are `PALETTE[0]`).
const PEER_COLOUR: RGBColor = RGBColor(213, 94, 0);

/// Width in pixels of `text` at `size` px in the registered font (a
/// generous estimate when the font cannot measure).
fn text_width(text: &str, size: u32) -> u32 {
    use plotters::style::{FontDesc, FontFamily, FontStyle};
    let font = FontDesc::new(FontFamily::SansSerif, size as f64, FontStyle::Normal);
    font.box_size(text).map_or(text.chars().count() as u32 * size * 6 / 10, |(w, _)| w)
}

/// `v` with three significant digits (0.0206, 64.0, 1592): bars of any
/// magnitude keep a readable value.
fn three_digits(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

/// One bar: a median with the min–max spread of the samples behind it.
#[derive(Debug, Clone)]
pub struct Bar {
    pub label: String,
    pub median: f64,
    /// (min, max) of the samples, drawn as a whisker; `None`: one value.
    pub spread: Option<(f64, f64)>,
    /// Another program's run (`--peers`): drawn in the peers' colour.
    pub peer: bool,
}

/// A horizontal bar chart as `<dir>/<name>.png` and `.svg`. The label
/// column is as wide as the longest label, so no label is cut.
pub fn bar_chart(dir: &Path, name: &str, title: &str, bars: &[Bar]) -> Result<()> {
    if bars.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
    register_font()?;
    let label_width = bars.iter().map(|b| text_width(&b.label, 14)).max().unwrap_or(0) + 20;
    let w = (label_width + 640).max(text_width(title, 20) + 60);
    let h = 130 + 28 * bars.len() as u32;
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = plotters::prelude::BitMapBackend::with_buffer(&mut rgb, (w, h));
        draw_bars(root, title, label_width, bars)?;
    }
    write_rgb8_png(&dir.join(format!("{name}.png")), w, h, &rgb)?;
    let mut svg = String::new();
    {
        let root = plotters::prelude::SVGBackend::with_string(&mut svg, (w, h));
        draw_bars(root, title, label_width, bars)?;
    }
    crate::fsio::write_output(&dir.join(format!("{name}.svg")), svg.as_bytes())
}

fn draw_bars<B: plotters::prelude::DrawingBackend>(backend: B, title: &str, label_width: u32, bars: &[Bar]) -> Result<()> {
    use plotters::prelude::*;
    use plotters::style::text_anchor::{HPos, Pos, VPos};
    let root = backend.into_drawing_area();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let top = bars.iter().map(|b| b.spread.map_or(b.median, |s| s.1).max(b.median)).fold(0.0, f64::max);
        let max = top.max(1e-9) * 1.2;
        let n = bars.len() as f64;
        // Bar i spans [n-1-i, n-i] on a continuous axis (first bar on top);
        // its label is drawn at its centre, right-aligned to the axis.
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(35)
            .y_label_area_size(label_width)
            .build_cartesian_2d(0.0..max, 0.0..n)
            .map_err(|e| e.to_string())?;
        let centre = |i: usize| n - 0.5 - i as f64;
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(0)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        let label_style = ("sans-serif", 14).into_font().into_text_style(&root).pos(Pos::new(HPos::Right, VPos::Center));
        let value_style = ("sans-serif", 13).into_font().into_text_style(&root).pos(Pos::new(HPos::Left, VPos::Center));
        for (i, b) in bars.iter().enumerate() {
            let colour = if b.peer { PEER_COLOUR } else { PALETTE[0] };
            let (lo_y, hi_y) = (centre(i) - 0.38, centre(i) + 0.38);
            chart.draw_series(std::iter::once(Rectangle::new([(0.0, lo_y), (b.median, hi_y)], colour.mix(0.85).filled()))).map_err(|e| e.to_string())?;
            let (ax, ay) = chart.backend_coord(&(0.0, centre(i)));
            root.draw(&Text::new(b.label.clone(), (ax - 8, ay), label_style.clone())).map_err(|e| e.to_string())?;
            // The whisker: min to max, through the bar's centre.
            if let Some((lo, hi)) = b.spread {
                let (x0, y) = chart.backend_coord(&(lo, centre(i)));
                let (x1, _) = chart.backend_coord(&(hi, centre(i)));
                root.draw(&PathElement::new(vec![(x0, y), (x1, y)], BLACK.stroke_width(2))).map_err(|e| e.to_string())?;
                for x in [x0, x1] {
                    root.draw(&PathElement::new(vec![(x, y - 5), (x, y + 5)], BLACK.stroke_width(2))).map_err(|e| e.to_string())?;
                }
            }
            let end = b.spread.map_or(b.median, |s| s.1.max(b.median));
            let (vx, vy) = chart.backend_coord(&(end, centre(i)));
            root.draw(&Text::new(three_digits(b.median), (vx + 6, vy), value_style.clone())).map_err(|e| e.to_string())?;
        }
        if bars.iter().any(|b| b.peer) {
            let (w, _) = root.dim_in_pixel();
            let x = w as i32 - 230;
            root.draw(&Rectangle::new([(x, 40), (x + 14, 52)], PALETTE[0].filled())).map_err(|e| e.to_string())?;
            root.draw(&Text::new("volbench", (x + 20, 39), ("sans-serif", 14).into_font())).map_err(|e| e.to_string())?;
            root.draw(&Rectangle::new([(x + 100, 40), (x + 114, 52)], PEER_COLOUR.filled())).map_err(|e| e.to_string())?;
            root.draw(&Text::new("peer", (x + 120, 39), ("sans-serif", 14).into_font())).map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
        Ok(())
    };
    draw().map_err(|e| anyhow::anyhow!("drawing '{title}': {e}"))
}

/// One cell of a montage: an image and, beside it, its difference from the
/// reference (×10).
#[derive(Debug, Clone)]
pub struct Tile {
    pub label: String,
    pub image: RgbaImage,
    pub diff: Option<RgbaImage>,
}

/// Cells (image + difference) per grid row.
const MONTAGE_COLUMNS: u32 = 3;
const TILE: u32 = 200;
const CAPTION: u32 = 22;

/// A grid of images: `reference` first (alone in its cell), then each tile's
/// image beside its ×10 difference, captioned; `title` above.
pub fn montage(path: &Path, title: &str, reference: Option<&RgbaImage>, tiles: &[Tile]) -> Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let cells: Vec<(String, Option<&RgbaImage>, Option<&RgbaImage>)> = reference
        .map(|r| ("f64 reference".to_string(), Some(r), None))
        .into_iter()
        .chain(tiles.iter().map(|t| (t.label.clone(), Some(&t.image), t.diff.as_ref())))
        .collect();
    anyhow::ensure!(!cells.is_empty(), "montage {}: no image", path.display());
    let gap = 12u32;
    let cell_w = 2 * TILE + gap;
    let cell_h = TILE + CAPTION + gap;
    let rows = (cells.len() as u32).div_ceil(MONTAGE_COLUMNS);
    let header = 34u32;
    let (w, h) = (MONTAGE_COLUMNS * cell_w + gap, header + rows * cell_h);
    let mut rgb = vec![0u8; (w as usize) * (h as usize) * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<_>| anyhow::anyhow!("montage {}: {e}", path.display());
        root.fill(&WHITE).map_err(err)?;
        let note = if reference.is_some() || tiles.iter().any(|t| t.diff.is_some()) {
            "each run: image | ×10 difference from the f64 reference"
        } else {
            "no image reference: these methods report their own error measure"
        };
        root.draw(&Text::new(format!("{title}  ({note})"), (gap as i32, 8), ("sans-serif", 17).into_font())).map_err(err)?;
        for (k, (label, image, diff)) in cells.iter().enumerate() {
            let (cx, cy) = ((k as u32 % MONTAGE_COLUMNS) * cell_w + gap, header + (k as u32 / MONTAGE_COLUMNS) * cell_h);
            // A caption longer than the cell is cut with an ellipsis, never overdrawn.
            let chars: Vec<char> = label.chars().collect();
            let mut n = chars.len();
            let mut caption = label.clone();
            while n > 1 && text_width(&caption, 14) > cell_w - gap {
                n -= 1;
                caption = chars[..n].iter().collect::<String>() + "…";
            }
            root.draw(&Text::new(caption, (cx as i32, cy as i32 + 2), ("sans-serif", 14).into_font())).map_err(err)?;
            for (col, img) in [image, diff].into_iter().enumerate() {
                let Some(img) = img else { continue };
                let x0 = cx + col as u32 * TILE;
                let y0 = cy + CAPTION;
                for ty in 0..TILE {
                    for tx in 0..TILE {
                        let sx = (tx as u64 * img.width as u64 / TILE as u64) as usize;
                        let sy = (ty as u64 * img.height as u64 / TILE as u64) as usize;
                        let p = img.pixels.get(sy * img.width as usize + sx).copied().unwrap_or([1.0; 4]);
                        let c = |v: f32| if v.is_finite() { (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8 } else { 255 };
                        let _ = root.draw_pixel(((x0 + tx) as i32, (y0 + ty) as i32), &RGBColor(c(p[0]), c(p[1]), c(p[2])));
                    }
                }
            }
        }
        root.present().map_err(err)?;
    }
    write_rgb8_png(path, w, h, &rgb)
}

/// How a scatter point is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Filled,
    Ring,
    /// Another program's run (`--peers`).
    Triangle,
}

/// One point of a time-against-error scatter.
#[derive(Debug, Clone)]
pub struct ScatterPoint {
    pub label: String,
    /// The colour group (an integrator, a method, a peer), in the legend.
    pub series: String,
    pub marker: Marker,
    pub time_ms: f64,
    pub error: f64,
    pub on_front: bool,
}

/// Frame time (x) against error (y), both logarithmic; the Pareto front is
/// joined by a line and its points labelled; one colour per series.
pub fn time_error_scatter(path: &Path, title: &str, y_desc: &str, legend_note: &str, points: &[ScatterPoint]) -> Result<()> {
    use plotters::prelude::*;
    register_font()?;
    let points: Vec<&ScatterPoint> = points.iter().filter(|p| p.time_ms > 0.0 && p.time_ms.is_finite() && p.error.is_finite()).collect();
    anyhow::ensure!(!points.is_empty(), "{}: nothing to plot (no run with a time and an error)", path.display());
    let mut series: Vec<&str> = Vec::new();
    for p in &points {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    let colour = |s: &str| PALETTE[series.iter().position(|&n| n == s).unwrap_or(0) % PALETTE.len()];
    let floor = 1e-9;
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0f64, f64::MAX, 0f64);
    for p in &points {
        t0 = t0.min(p.time_ms);
        t1 = t1.max(p.time_ms);
        e0 = e0.min(p.error.max(floor));
        e1 = e1.max(p.error.max(floor));
    }
    let (x_range, y_range) = ((t0 / 1.3, t1 * 1.6), (e0 / 1.5, e1 * 1.5));
    let legend_w = series.iter().map(|s| text_width(s, 14)).max().unwrap_or(0).max(text_width(legend_note, 13).min(320)) + 50;
    let (plot_w, h) = (900u32, 700u32);
    let w = plot_w + legend_w;
    let mut rgb = vec![0u8; (w as usize) * (h as usize) * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let (plot, legend) = root.split_horizontally(plot_w);
        let draw = || -> Result<(), Box<dyn std::error::Error>> {
            root.fill(&WHITE)?;
            let mut chart = ChartBuilder::on(&plot)
                .caption(title, ("sans-serif", 20))
                .margin(20)
                .x_label_area_size(50)
                .y_label_area_size(80)
                .build_cartesian_2d(
                    (x_range.0..x_range.1).log_scale().with_key_points(log_ticks(x_range.0, x_range.1)),
                    (y_range.0..y_range.1).log_scale().with_key_points(log_ticks(y_range.0, y_range.1)),
                )?;
            chart
                .configure_mesh()
                .x_desc("median frame time (ms)")
                .y_desc(y_desc)
                .label_style(("sans-serif", 15))
                .axis_desc_style(("sans-serif", 17))
                .x_label_formatter(&|v| if *v >= 10.0 { format!("{v:.0}") } else { format!("{v:.1}") })
                .y_label_formatter(&|v| format!("{v:.1e}"))
                .draw()?;
            let mut front: Vec<&ScatterPoint> = points.iter().copied().filter(|p| p.on_front).collect();
            front.sort_by(|a, b| a.time_ms.total_cmp(&b.time_ms));
            chart.draw_series(LineSeries::new(front.iter().map(|p| (p.time_ms, p.error.max(floor))), BLACK.stroke_width(1)))?;
            for p in &points {
                let c = colour(&p.series);
                let at = (p.time_ms, p.error.max(floor));
                match p.marker {
                    Marker::Filled => chart.draw_series(std::iter::once(Circle::new(at, 5, c.filled())))?,
                    Marker::Ring => chart.draw_series(std::iter::once(Circle::new(at, 5, c.stroke_width(2))))?,
                    Marker::Triangle => chart.draw_series(std::iter::once(TriangleMarker::new(at, 7, c.filled())))?,
                };
            }
            // Labels stacked upward from each front point so neighbours don't overlap.
            for (i, p) in front.iter().enumerate() {
                let anchor = chart.backend_coord(&(p.time_ms, p.error.max(floor)));
                plot.draw(&Text::new(p.label.clone(), (anchor.0 + 8, anchor.1 - 16 * (i as i32 % 3) - 4), ("sans-serif", 13).into_font()))?;
            }
            legend.draw(&Text::new("colours", (10, 60), ("sans-serif", 15).into_font()))?;
            for (i, name) in series.iter().enumerate() {
                let y = 90 + 22 * i as i32;
                legend.draw(&Circle::new((16, y + 7), 5, colour(name).filled()))?;
                legend.draw(&Text::new(if name.is_empty() { "-" } else { *name }, (28, y), ("sans-serif", 14).into_font()))?;
            }
            let mut y = 110 + 22 * series.len() as i32;
            for line in legend_note.split('\n').chain(["line: Pareto front", "(labelled: on the front)"]) {
                legend.draw(&Text::new(line.to_string(), (10, y), ("sans-serif", 13).into_font()))?;
                y += 18;
            }
            root.present()?;
            Ok(())
        };
        draw().map_err(|e| anyhow::anyhow!("drawing {}: {e}", path.display()))?;
    }
    write_rgb8_png(path, w, h, &rgb)
}

/// Mark the points no other point dominates (faster or equal and less or
/// equally wrong, strictly better in one). `key` gives (time, error), or
/// `None` for a point that takes no part (a failed run).
pub fn mark_front<T>(points: &mut [T], key: impl Fn(&T) -> Option<(f64, f64)>, mut set: impl FnMut(&mut T, bool)) {
    let snapshot: Vec<Option<(f64, f64)>> = points.iter().map(&key).collect();
    for (i, p) in points.iter_mut().enumerate() {
        let on = snapshot[i].is_some_and(|(t, e)| {
            !snapshot.iter().enumerate().any(|(j, o)| j != i && o.is_some_and(|(tj, ej)| tj <= t && ej <= e && (tj < t || ej < e)))
        });
        set(p, on);
    }
}


/// Ticks of a log axis at 1, 2, 3, 5, 7 × 10^k: a plot often spans less
/// than a decade, where the log axis would otherwise show no label at all.
pub(crate) fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mut v = Vec::new();
    let mut decade = 10f64.powf(lo.log10().floor());
    while decade <= hi {
        for m in [1.0, 2.0, 3.0, 5.0, 7.0] {
            let t = m * decade;
            if t >= lo && t <= hi {
                v.push(t);
            }
        }
        decade *= 10.0;
    }
    v
}

/// A count as an axis label: 500, 20 K, 4 M, 1.5 G.
pub(crate) fn count_label(v: f64) -> String {
    let (x, unit) = match v.abs() {
        a if a >= 1e9 => (v / 1e9, " G"),
        a if a >= 1e6 => (v / 1e6, " M"),
        a if a >= 1e3 => (v / 1e3, " K"),
        _ => (v, ""),
    };
    let digits = if x.fract().abs() < 1e-9 { 0 } else { 1 };
    format!("{x:.digits$}{unit}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_label_every_axis_and_counts_read_short() {
        assert_eq!(log_ticks(300_000.0, 6_000_000.0), vec![300_000.0, 500_000.0, 700_000.0, 1e6, 2e6, 3e6, 5e6]);
        assert_eq!(count_label(500_000.0), "500 K");
        assert_eq!(count_label(4_000_000.0), "4 M");
        assert_eq!(count_label(1_500_000_000.0), "1.5 G");
        assert_eq!(count_label(20.0), "20");
    }

    fn image(v: f32) -> RgbaImage {
        RgbaImage { width: 8, height: 8, pixels: vec![[v, v, v, 1.0]; 64] }
    }

    #[test]
    fn figures_are_written() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let bars = [
            Bar { label: "a long label for one method:integrator=average".into(), median: 3.0, spread: Some((2.0, 4.0)), peer: false },
            Bar { label: "peer vtk/gpu".into(), median: 5.0, spread: None, peer: true },
        ];
        bar_chart(&dir, "t", "frame time", &bars).unwrap();
        assert!(dir.join("t.png").exists() && dir.join("t.svg").exists());
        let tiles = [Tile { label: "run".into(), image: image(0.5), diff: Some(image(0.1)) }];
        montage(&dir.join("m.png"), "dataset", Some(&image(0.4)), &tiles).unwrap();
        let mut pts = vec![
            ScatterPoint { label: "a".into(), series: "x".into(), marker: Marker::Filled, time_ms: 1.0, error: 0.1, on_front: false },
            ScatterPoint { label: "b".into(), series: "y".into(), marker: Marker::Triangle, time_ms: 2.0, error: 0.2, on_front: false },
        ];
        mark_front(&mut pts, |p| Some((p.time_ms, p.error)), |p, on| p.on_front = on);
        assert!(pts[0].on_front && !pts[1].on_front);
        time_error_scatter(&dir.join("s.png"), "t", "RMSE", "", &pts).unwrap();
        assert!(dir.join("s.png").exists());
    }

    #[test]
    fn values_keep_three_significant_digits() {
        assert_eq!([three_digits(0.02064), three_digits(64.0), three_digits(1591.8), three_digits(0.0)], ["0.0206", "64.0", "1592", "0"]);
    }

    #[test]
    fn front_keeps_only_undominated_points() {
        let mut pts = [(1.0, 3.0, false), (2.0, 2.0, false), (3.0, 3.0, false), (0.5, f64::NAN, false)];
        mark_front(&mut pts, |p| (!p.1.is_nan()).then_some((p.0, p.1)), |p, on| p.2 = on);
        assert_eq!(pts.map(|p| p.2), [true, true, false, false]);
    }
}
