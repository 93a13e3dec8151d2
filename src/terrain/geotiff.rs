//! Single-band GeoTIFF elevation grids (the `tiff` crate decodes; this
//! checks). One grey band of any integer or float sample type; the pixel
//! size comes from GeoTIFF's ModelPixelScale tag when present (else 1),
//! missing samples from GDAL's nodata tag (and NaN). The decoder's buffer
//! limits are set from the grid size volbench accepts, and the dimensions
//! are checked before the image is decoded.

use anyhow::{bail, Result};
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;
use tiff::ColorType;

use super::{Heightmap, MAX_SAMPLES};

/// Largest decoded image (bytes): a float64 grid of `MAX_SAMPLES` samples.
const MAX_DECODED_BYTES: usize = MAX_SAMPLES * 8;

pub fn parse_geotiff_bytes(name: &str, bytes: &[u8]) -> Result<Heightmap> {
    let err = |e: tiff::TiffError| anyhow::anyhow!("{name}: not a readable TIFF: {}", crate::fsio::clip_message(&e.to_string()));
    let mut limits = Limits::default();
    limits.decoding_buffer_size = MAX_DECODED_BYTES;
    limits.intermediate_buffer_size = MAX_DECODED_BYTES;
    let mut dec = Decoder::new(std::io::Cursor::new(bytes)).map_err(err)?.with_limits(limits);
    let (w, h) = dec.dimensions().map_err(err)?;
    let (nx, ny) = (w as usize, h as usize);
    super::check_grid(name, nx, ny)?;
    match dec.colortype().map_err(err)? {
        ColorType::Gray(_) => {}
        other => bail!("{name}: a height grid must be one grey band, this TIFF is {other:?}"),
    }
    let spacing = match dec.get_tag_f64_vec(Tag::ModelPixelScaleTag) {
        Ok(s) if s.len() >= 2 => [s[0].abs(), s[1].abs()],
        _ => [1.0, 1.0],
    };
    let nodata = match dec.get_tag_ascii_string(Tag::GdalNodata) {
        Ok(text) => {
            let t = text.trim_matches(|c: char| c == '\0' || c.is_whitespace());
            match t.parse::<f64>() {
                Ok(v) => Some(v),
                Err(_) => bail!("{name}: GDAL nodata value '{}' is not a number", crate::fsio::clip_message(t)),
            }
        }
        Err(_) => None,
    };
    // The decoded samples in their own type, made heights one by one
    // (no f64 copy of the grid: peak is the decoded image plus the heights).
    macro_rules! heights {
        ($v:expr) => {{
            let v = $v;
            Heightmap::from_fn(name, nx, ny, v.len(), |i| v[i] as f64, nodata, spacing)
        }};
    }
    match dec.read_image().map_err(err)? {
        DecodingResult::U8(v) => heights!(v),
        DecodingResult::U16(v) => heights!(v),
        DecodingResult::U32(v) => heights!(v),
        DecodingResult::U64(v) => heights!(v),
        DecodingResult::I8(v) => heights!(v),
        DecodingResult::I16(v) => heights!(v),
        DecodingResult::I32(v) => heights!(v),
        DecodingResult::I64(v) => heights!(v),
        DecodingResult::F16(v) => heights!(v.into_iter().map(f32::from).collect::<Vec<_>>()),
        DecodingResult::F32(v) => heights!(v),
        DecodingResult::F64(v) => heights!(v),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tiff::encoder::{colortype, TiffEncoder};

    fn encode_f32(w: u32, h: u32, data: &[f32], nodata: Option<&str>) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        let mut enc = TiffEncoder::new(&mut out).unwrap();
        let mut img = enc.new_image::<colortype::Gray32Float>(w, h).unwrap();
        img.encoder().write_tag(Tag::ModelPixelScaleTag, &[30.0f64, 20.0, 0.0][..]).unwrap();
        if let Some(n) = nodata {
            img.encoder().write_tag(Tag::GdalNodata, n).unwrap();
        }
        img.write_data(data).unwrap();
        out.into_inner()
    }

    #[test]
    fn reads_grey_floats_with_scale_and_nodata() {
        let b = encode_f32(3, 2, &[1.0, 2.0, -9999.0, 4.0, f32::NAN, 6.0], Some("-9999"));
        let m = parse_geotiff_bytes("g.tif", &b).unwrap();
        assert_eq!((m.nx, m.ny, m.spacing), (3, 2, [30.0, 20.0]));
        assert_eq!(m.heights, vec![1.0, 2.0, 1.0, 4.0, 1.0, 6.0]);
        assert_eq!(m.nodata_filled, 2);
    }

    #[test]
    fn bad_tiffs_are_errors_naming_the_file() {
        let mut out = std::io::Cursor::new(Vec::new());
        TiffEncoder::new(&mut out).unwrap().write_image::<colortype::RGB8>(2, 2, &[0u8; 12]).unwrap();
        let e = format!("{:#}", parse_geotiff_bytes("rgb.tif", out.get_ref()).unwrap_err());
        assert!(e.starts_with("rgb.tif") && e.contains("grey band"), "{e}");
        let b = encode_f32(2, 2, &[1.0; 4], Some("abc"));
        let e = format!("{:#}", parse_geotiff_bytes("n.tif", &b).unwrap_err());
        assert!(e.contains("nodata value 'abc'"), "{e}");
        let b = encode_f32(2, 2, &[1.0; 4], None);
        let e = format!("{:#}", parse_geotiff_bytes("t.tif", &b[..b.len() / 2]).unwrap_err());
        assert!(e.starts_with("t.tif"), "{e}");
        let e = format!("{:#}", parse_geotiff_bytes("x.tif", b"II*\0garbage").unwrap_err());
        assert!(e.starts_with("x.tif"), "{e}");
        let b = encode_f32(1, 5, &[1.0; 5], None);
        let e = format!("{:#}", parse_geotiff_bytes("s.tif", &b).unwrap_err());
        assert!(e.contains("1x5"), "{e}");
    }
}
