//! Transfer-function JSON reader: any text gives a transfer function or an
//! error naming the file, never a panic. A function that loads has sorted,
//! finite control points, colours in [0, 1] and attenuation within f32 (the
//! renderers' type), over an ordinary and a constant field's scalar range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use volbench::scene::tf_file::parse_tf;

fuzz_target!(|data: &[u8]| {
    // `load_tf` refuses non-UTF-8 files before parsing.
    let Ok(text) = std::str::from_utf8(data) else { return };
    for (range, diagonal) in [((0.0, 1.0), 1.0), ((2.5, 2.5), 1e-3), ((-1e30, 1e30), 1e12)] {
        match parse_tf(text, "fuzz.json", "fuzz", range, diagonal) {
            Ok(tf) => {
                assert!(!tf.points.is_empty());
                assert!(tf.points.windows(2).all(|w| w[0].scalar <= w[1].scalar), "{tf:?}");
                for p in &tf.points {
                    assert!(p.scalar.is_finite(), "{p:?}");
                    assert!(p.color.iter().all(|c| (0.0..=1.0).contains(c)), "{p:?}");
                    assert!(p.attenuation >= 0.0 && p.attenuation <= f32::MAX as f64, "{p:?}");
                }
                assert!(tf.points.iter().any(|p| p.attenuation > 0.0));
            }
            Err(e) => assert!(format!("{e:#}").starts_with("fuzz.json: "), "{e:#}"),
        }
    }
});
