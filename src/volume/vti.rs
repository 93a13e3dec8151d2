//! VTK XML ImageData (`.vti`) reader.
//!
//! One `Piece` covering the `WholeExtent`; `Origin`, `Spacing` and an
//! axis-aligned `Direction`; `byte_order` little or big; `header_type`
//! UInt32 or UInt64; `compressor` none, `vtkZLibDataCompressor`,
//! `vtkLZ4DataCompressor` or `vtkLZMADataCompressor`. The point
//! data array read is the one named by the caller, else the `PointData`'s
//! active `Scalars`, else the first one-component array. Its data may be
//! `ascii`, inline `binary` (base64) or `appended` (raw or base64), of type
//! UInt8, Int16, UInt16, Float32 (Int8 and Int32 convert, see `decode`).
//!
//! The file layer (appended data, binary headers, compressed blocks) is
//! `crate::vtk_xml`, shared with the `.vtu` mesh reader.

use anyhow::{anyhow, bail, Result};
use std::path::Path;

use super::decode::{byte_len, decode_binary, parse_ascii, RawType, Tokens};
use crate::vtk_xml::{array_payload, numbers, root_layout, split_appended, Appended};
use super::{check_dims, from_steps, stem_of, Volume};

/// Reads a `.vti` file's point array `array` (`None`: see the module note).
pub fn read_vti(path: impl AsRef<Path>, array: Option<&str>) -> Result<Volume> {
    let path = path.as_ref();
    let bytes = crate::fsio::read_input(path, "VTK XML ImageData file", crate::fsio::MAX_INPUT_BYTES)?;
    parse_vti_bytes(&path.display().to_string(), &bytes, array)
}

fn raw_type(name: &str, t: &str) -> Result<RawType> {
    Ok(match t {
        "Int8" => RawType::I8,
        "UInt8" => RawType::U8,
        "Int16" => RawType::I16,
        "UInt16" => RawType::U16,
        "Int32" => RawType::I32,
        "Float32" => RawType::F32,
        _ => bail!("{name}: unsupported DataArray type '{t}'; supported: UInt8, Int16, UInt16, Float32, Int8, Int32"),
    })
}

/// Parses a VTK XML ImageData file from its bytes, reading the point array
/// `array` (`None`: the active scalars, else the first one-component array).
/// `name` starts every error and its stem names the volume. Never panics on
/// malformed input.
pub fn parse_vti_bytes(name: &str, bytes: &[u8], array: Option<&str>) -> Result<Volume> {
    let parts = split_appended(name, bytes)?;
    let doc = roxmltree::Document::parse(&parts.xml).map_err(|e| anyhow!("{name}: bad XML: {e}"))?;
    let root = doc.root_element();
    let layout = root_layout(name, root, "ImageData")?;
    let appended = Appended::new(&doc, parts.appended.as_ref());

    // ---- grid
    let image = root
        .children()
        .find(|n| n.has_tag_name("ImageData"))
        .ok_or_else(|| anyhow!("{name}: no <ImageData> element"))?;
    let whole: Vec<i64> = numbers(name, image, "WholeExtent", 6)?.ok_or_else(|| anyhow!("{name}: <ImageData> has no WholeExtent"))?;
    let mut d = [0u64; 3];
    for a in 0..3 {
        let (lo, hi) = (whole[2 * a], whole[2 * a + 1]);
        if hi < lo {
            bail!("{name}: WholeExtent axis {a} runs from {lo} down to {hi}: size 0");
        }
        d[a] = hi.abs_diff(lo).saturating_add(1);
    }
    let dims = check_dims(name, d)?;
    let count = dims[0] * dims[1] * dims[2];
    let origin: Vec<f64> = numbers(name, image, "Origin", 3)?.unwrap_or(vec![0.0; 3]);
    let spacing: Vec<f64> = numbers(name, image, "Spacing", 3)?.unwrap_or(vec![1.0; 3]);
    let dir: Vec<f64> = numbers(name, image, "Direction", 9)?.unwrap_or(vec![1., 0., 0., 0., 1., 0., 0., 0., 1.]);
    // Direction is row-major; column a is index axis a's world direction.
    let steps: [[f64; 3]; 3] = std::array::from_fn(|a| std::array::from_fn(|w| dir[3 * w + a] * spacing[a]));
    // World position of the extent's first point (VTK's Origin is index 0).
    let first: [f64; 3] =
        std::array::from_fn(|w| origin[w] + (0..3).map(|a| whole[2 * a] as f64 * steps[a][w]).sum::<f64>());

    let pieces: Vec<_> = image.children().filter(|n| n.has_tag_name("Piece")).collect();
    let piece = match pieces.as_slice() {
        [p] => *p,
        [] => bail!("{name}: <ImageData> has no <Piece>"),
        _ => bail!("{name}: {} pieces: only single-piece files are supported", pieces.len()),
    };
    let extent: Vec<i64> = numbers(name, piece, "Extent", 6)?.ok_or_else(|| anyhow!("{name}: <Piece> has no Extent"))?;
    if extent != whole {
        bail!("{name}: the piece's Extent {extent:?} is not the WholeExtent {whole:?}");
    }
    let point_data = piece
        .children()
        .find(|n| n.has_tag_name("PointData"))
        .ok_or_else(|| anyhow!("{name}: the piece has no <PointData>"))?;
    let arrays: Vec<_> = point_data.children().filter(|n| n.has_tag_name("DataArray")).collect();
    let comps = |n: &roxmltree::Node| n.attribute("NumberOfComponents").unwrap_or("1").trim() == "1";
    let listing = || {
        arrays
            .iter()
            .map(|a| format!("'{}' ({} components)", a.attribute("Name").unwrap_or("?"), a.attribute("NumberOfComponents").unwrap_or("1")))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = match array.or(point_data.attribute("Scalars")) {
        Some(want) => arrays
            .iter()
            .find(|a| a.attribute("Name") == Some(want))
            .ok_or_else(|| anyhow!("{name}: no point data array named '{want}'; found: {}", listing()))?,
        None => arrays
            .iter()
            .find(|a| comps(a))
            .ok_or_else(|| anyhow!("{name}: no one-component point data array; found: {}", listing()))?,
    };
    let aname = chosen.attribute("Name").unwrap_or("(unnamed)");
    let what = format!("DataArray '{aname}'");
    if !comps(chosen) {
        bail!("{name}: {what} has {} components; a volume needs one", chosen.attribute("NumberOfComponents").unwrap_or("?"));
    }
    let ty_name = chosen.attribute("type").ok_or_else(|| anyhow!("{name}: {what} has no type"))?;
    let ty = raw_type(name, ty_name)?;
    let expected = byte_len(name, count, ty)?;

    // ---- the data
    let samples = match array_payload(name, &what, *chosen, appended.as_ref(), layout, expected)? {
        Some(payload) => decode_binary(name, payload.into_vec(name, &what)?.into(), ty, layout.endian, count)?,
        None => {
            let text = chosen.text().unwrap_or("");
            let mut tokens = Tokens::new(text.as_bytes());
            let s = parse_ascii(name, &what, &mut tokens, ty, ty_name, count, 0)?;
            if tokens.next_token().is_some() {
                bail!("{name}: header/size mismatch: {what} holds more than the {count} values its extent needs");
            }
            s
        }
    };
    from_steps(name, stem_of(name), dims, steps, first, samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Samples;

    /// A ramp VTK 9.7.2 wrote with each compressor (UInt64 headers,
    /// appended raw, 64-byte blocks: `tests/fixtures/vtk_xml/make.py`).
    #[test]
    fn vtk_written_compressed_images() {
        let files: [(&str, &[u8]); 3] = [
            ("zlib", include_bytes!("../../tests/fixtures/vtk_xml/ramp_zlib.vti")),
            ("lz4", include_bytes!("../../tests/fixtures/vtk_xml/ramp_lz4.vti")),
            ("lzma", include_bytes!("../../tests/fixtures/vtk_xml/ramp_lzma.vti")),
        ];
        let want: Vec<f32> = (0..3).flat_map(|k| (0..4).flat_map(move |j| (0..5).map(move |i| (i + 10 * j + 100 * k) as f32 + 0.25))).collect();
        for (what, bytes) in files {
            let v = parse_vti_bytes("ramp.vti", bytes, None).unwrap_or_else(|e| panic!("{what}: {e:#}"));
            assert_eq!(v.dims(), [5, 4, 3], "{what}");
            assert_eq!(v.spacing(), [1.0, 0.5, 2.0], "{what}");
            assert_eq!(v.samples(), &Samples::F32(want.clone()), "{what}");
            for cut in (0..bytes.len()).step_by(31) {
                if let Err(e) = parse_vti_bytes("cut.vti", &bytes[..cut], None) {
                    assert!(format!("{e:#}").starts_with("cut.vti"), "{what}: {e:#}");
                }
            }
        }
    }
}
