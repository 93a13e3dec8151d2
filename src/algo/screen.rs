//! The pixels a compute pass must run over: the one rule for the
//! rectangle that holds a set of projected points (tet-raycast's boundary
//! vertices, the ray casters' box corners). On llvmpipe an invocation with
//! nothing to do still runs its whole shader masked (docs/compute-speed.md,
//! third round), so passes dispatch over this rectangle only.

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

/// The stride of the order in which a pass of `rows` rows of workgroups
/// takes them: the pass's row r (in dispatch order) is image row
/// `r * stride % rows`. lavapipe's compute thread pool hands each thread one
/// contiguous run of the dispatch's workgroups (`lp_cs_tpool`: the count
/// divided by the threads), so in image order one thread gets the top of
/// the image and another the bottom, and the frame waits for the costlier
/// part. A stride near the golden section of `rows`, coprime with it, spreads
/// every contiguous run of rows over the whole image. 1 (in order) for up
/// to 2 rows.
pub fn row_stride(rows: u32) -> u32 {
    if rows <= 2 {
        return 1;
    }
    let gcd = |mut a: u32, mut b: u32| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut s = ((f64::from(rows) * 0.618_033_988_749_895).round() as u32).max(1);
    while gcd(s, rows) != 1 {
        s += 1;
    }
    s
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
    fn the_row_order_is_a_permutation_that_spreads_each_half() {
        for rows in 1..200u32 {
            let s = row_stride(rows);
            let mut seen = vec![false; rows as usize];
            for r in 0..rows {
                seen[(r * s % rows) as usize] = true;
            }
            assert!(seen.iter().all(|&x| x), "rows {rows} stride {s}");
            if rows >= 16 {
                // The first half of the order reaches both halves of the image about equally.
                let top = (0..rows / 2).filter(|r| r * s % rows < rows / 2).count() as f64;
                assert!((top / f64::from(rows / 2) - 0.5).abs() < 0.2, "rows {rows} stride {s}: {top}");
            }
        }
    }
}
