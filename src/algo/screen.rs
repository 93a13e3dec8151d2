//! The pixels a compute pass must run over: the one rule for the
//! rectangle that holds a set of projected points (tet-raycast's boundary
//! vertices, the ray casters' box corners). On llvmpipe an invocation with
//! nothing to do still runs its whole shader masked (docs/compute-speed.md,
//! "What llvmpipe does"), so passes dispatch over this rectangle only.

/// Inclusive pixel bounds `[x0, y0, x1, y1]` of an empty rectangle.
pub const NO_PIXELS: [u32; 4] = [1, 1, 0, 0];

/// The inclusive pixel bounds `[x0, y0, x1, y1]` of `points` (pixel
/// coordinates, where x + 0.5 is the centre of pixel x), padded by `pad`
/// pixels and clamped to an image of `size`; [`NO_PIXELS`] when none of
/// it is on the image (or there are no points). Every finite point's
/// pixel, and its neighbours within `pad`, are inside.
pub fn pixel_bounds(points: impl IntoIterator<Item = [f64; 2]>, pad: f64, size: [u32; 2]) -> [u32; 4] {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let size = size.map(f64::from);
    let a: [f64; 2] = std::array::from_fn(|k| (lo[k] - pad).floor().max(0.0));
    let b: [f64; 2] = std::array::from_fn(|k| (hi[k] + pad).ceil().min(size[k] - 1.0));
    if !(a[0] <= b[0] && a[1] <= b[1]) {
        return NO_PIXELS;
    }
    [a[0] as u32, a[1] as u32, b[0] as u32, b[1] as u32]
}

/// The workgroups of `group`-pixel tiles that cover the inclusive pixel
/// bounds `rect`: (first group, group counts), for `dispatch_base`. Zero
/// counts for an empty rectangle.
pub fn groups_over(rect: [u32; 4], group: [u32; 2]) -> ([u32; 3], [u32; 3]) {
    if rect[0] > rect[2] || rect[1] > rect[3] {
        return ([0; 3], [0, 0, 1]);
    }
    let base = [rect[0] / group[0], rect[1] / group[1]];
    let end = [rect[2] / group[0] + 1, rect[3] / group[1] + 1];
    ([base[0], base[1], 0], [end[0] - base[0], end[1] - base[1], 1])
}

/// The pixels (inclusive bounds, clamped to an image of `size`) of the
/// workgroups `groups` from `base`, each `group` pixels: what a pass over
/// them may write; [`NO_PIXELS`] when there are none.
pub fn pixels_of_groups(base: [u32; 3], groups: [u32; 3], group: [u32; 2], size: [u32; 2]) -> [u32; 4] {
    if groups[0] == 0 || groups[1] == 0 || size[0] == 0 || size[1] == 0 {
        return NO_PIXELS;
    }
    let end = |k: usize| (u64::from(base[k] + groups[k]) * u64::from(group[k])).min(u64::from(size[k])) as u32;
    let (x0, y0) = (base[0] * group[0], base[1] * group[1]);
    if x0 >= size[0] || y0 >= size[1] {
        return NO_PIXELS;
    }
    [x0, y0, end(0) - 1, end(1) - 1]
}

/// The rows of workgroups a pass over `rows` rows dispatches when its
/// device shares the workgroups out in `runs` contiguous runs
/// (`DeviceInfo::compute_runs`): rows enough for `runs` runs of
/// ceil(rows / runs) each. The shader takes dispatch row y as tile row
/// `(y % len) * runs + y / len` (`interleaved_row` in
/// shaders/common/dispatch.glsl; len = ceil(rows / runs)) and skips rows
/// past `rows`, so run t gets the tile rows t, t + runs, t + 2 runs, ...:
/// every thread a share of every part of the image. In image order, on two
/// threads, one would march the top half of the image and the other the
/// bottom half, and the frame would wait for the costlier half.
pub fn interleaved_rows(rows: u32, runs: u32) -> u32 {
    if runs <= 1 {
        return rows;
    }
    rows.div_ceil(runs) * runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_hold_every_point_and_its_padding() {
        let r = pixel_bounds([[3.2, 4.7], [10.5, 2.0]], 1.0, [64, 32]);
        assert_eq!(r, [2, 1, 12, 6]);
        // Clamped to the image; off the image: nothing.
        assert_eq!(pixel_bounds([[-5.0, -5.0], [100.0, 100.0]], 2.0, [64, 32]), [0, 0, 63, 31]);
        assert_eq!(pixel_bounds([[70.0, 3.0], [80.0, 4.0]], 2.0, [64, 32]), NO_PIXELS);
        assert_eq!(pixel_bounds([], 2.0, [64, 32]), NO_PIXELS);
        assert_eq!(pixel_bounds([[f64::NAN, 1.0]], 2.0, [64, 32]), NO_PIXELS);
    }

    #[test]
    fn groups_cover_the_rectangle_and_no_more_tiles() {
        assert_eq!(groups_over([0, 0, 63, 31], [8, 8]), ([0, 0, 0], [8, 4, 1]));
        assert_eq!(groups_over([9, 7, 16, 8], [8, 8]), ([1, 0, 0], [2, 2, 1]));
        assert_eq!(groups_over(NO_PIXELS, [8, 8]).1, [0, 0, 1]);
    }

    #[test]
    fn interleaved_rows_give_each_run_every_runs_th_row_once() {
        for rows in 0..70u32 {
            for runs in 1..6u32 {
                let dispatched = interleaved_rows(rows, runs);
                assert!(dispatched >= rows && dispatched < rows + runs.max(1), "{rows} {runs}");
                // The shader's map (common/dispatch.glsl, interleaved_row).
                let len = rows.div_ceil(runs).max(1);
                let mut seen = vec![0; rows as usize];
                for y in 0..dispatched {
                    let row = if runs <= 1 { y } else { (y % len) * runs + y / len };
                    if row < rows {
                        seen[row as usize] += 1;
                        // Run t (a contiguous share of the dispatch) holds rows t mod runs.
                        if runs > 1 {
                            assert_eq!(row % runs, y / len, "{rows} {runs} {y}");
                        }
                    }
                }
                assert!(seen.iter().all(|&n| n == 1), "{rows} {runs}: {seen:?}");
            }
        }
    }
}
