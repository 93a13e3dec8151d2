//! A compute pass's target is cleared only where the frame before may have
//! written it (`CommandRecorder::storage_target`, `Image::zero_outside`):
//! no pixel of an earlier frame may survive into a later one.

mod common;

use volbench::algo::method::DataKind;
use volbench::algo::registry;
use volbench::harness::datasets::Dataset;
use volbench::harness::run::{run, RunConfig};
use volbench::mesh::split::hex_grid_to_tets;
use volbench::volume::{Samples, Volume};

/// The points of a `dims` grid of unit spacing, x fastest.
fn grid(dims: [usize; 3]) -> Vec<[f64; 3]> {
    let mut points = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                points.push([i as f64, j as f64, k as f64]);
            }
        }
    }
    points
}

/// A bar along x (`along_x`) or z, 4 times as long as it is wide: seen
/// lengthwise from one side of the orbit and end-on a quarter turn on.
fn bar_mesh(along_x: bool) -> Dataset {
    let dims = if along_x { [13, 4, 4] } else { [4, 4, 13] };
    let points = grid(dims);
    let scalars = points.iter().map(|p| (0.7 * p[0] + 0.5 * p[1] + 0.3 * p[2]).sin()).collect();
    Dataset::from_mesh(hex_grid_to_tets("bar", dims, points, scalars).unwrap(), false, "bar".into())
}

fn bar_volume(along_x: bool) -> Dataset {
    let dims = if along_x { [40, 10, 10] } else { [10, 10, 40] };
    let s = grid(dims).iter().map(|p| ((0.3 * p[0] + 0.5 * p[1] + 0.2 * p[2]) as f32).sin().abs()).collect();
    let v = Volume::new("bar", "bar", dims, [1.0; 3], [0.0; 3], Samples::F32(s)).unwrap();
    Dataset::from_volume(v, false, "bar".into())
}

/// After a frame a quarter turn before the reference view (a bar seen end-on
/// in one and lengthwise in the other: their rectangles differ), after
/// frames with the camera turned away (an empty rectangle), and zoomed in
/// (rectangles cut by the image's edges), the reference view's image is
/// bit for bit that of a run whose only frame had that view: at two image
/// sizes, for every compute pass that clears part of its target.
#[test]
fn no_pixel_of_an_earlier_frame_survives() {
    let methods = ["tet-raycast", "tet-raycast:adaptive=0.016", "pt-compute", "raycast-compute", "raycast-compute:adaptive=0.016"];
    for along_x in [true, false] {
        for method in methods {
            let spec = registry::builtin().parse_spec(method, &[]).unwrap();
            let dataset = if spec.info.data == DataKind::Volume { bar_volume(along_x) } else { bar_mesh(along_x) };
            let tf = dataset.default_transfer_function().unwrap();
            for size in [64u32, 112] {
                let image = |frames: usize, orbit_deg: f64, zoom: f64, fixed_frames: usize| {
                    let cfg = RunConfig {
                        width: size,
                        height: size + 16,
                        frames,
                        warmup: 0,
                        orbit_step: orbit_deg.to_radians(),
                        zoom,
                        fixed_frames,
                        ..RunConfig::default()
                    };
                    let ctx = common::context();
                    let out = run(&ctx, &spec, &dataset, &tf, &cfg).unwrap_or_else(|e| panic!("{method}: {e:#}"));
                    assert!(ctx.validation_messages().is_empty(), "{:?}", ctx.validation_messages());
                    out.image
                };
                for (frames, orbit, zoom, fixed, what) in
                    [(2, 90.0, 1.0, 0, "a quarter turn"), (2, 90.0, 1.0, 2, "turned-away frames"), (3, 35.0, 2.5, 0, "zoomed frames")]
                {
                    let alone = image(1, 0.0, zoom, 0);
                    assert!(alone.covered_pixels() > 0, "{method}: nothing in view");
                    let after = image(frames, orbit, zoom, fixed);
                    assert!(after.pixels == alone.pixels, "{method} (bar along x: {along_x}) at {size}: after {what} the reference view differs");
                }
            }
        }
    }
}
