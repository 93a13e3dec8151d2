//! Issue 35's `.vtu` memory bound, with the heap counted where it is taken
//! (`vk::MeteredAlloc`): reading a `.vtu` holds the file's bytes, its
//! arrays in their final types (8 bytes a coordinate or scalar, 4 a
//! connectivity entry, 1 a cell type) and at most one compressed block or
//! 64 KiB besides, so the peak is at most the file plus twice its arrays'
//! data (count × the declared type's size) plus a fixed overhead; counts
//! the data cannot hold are refused before anything their size is
//! allocated. Three shapes at two sizes each: zlib blocks inflating to
//! tens of MB, a raw appended array, ASCII text; and headers promising
//! more than the file holds. One test, so nothing else allocates meanwhile.

use std::io::Write as _;

use volbench::mesh::vtu::read_vtu;
use volbench::vk::{meter, MeteredAlloc};

#[global_allocator]
static ALLOC: MeteredAlloc = MeteredAlloc;

const FIXED: u64 = 4 << 20;

/// A piece with `points` as its only array: reading decodes it, then
/// fails (no point data to use as the scalar) before anything else.
fn points_only(np: usize, array: &str, appended: Option<&[u8]>, compressor: &str) -> Vec<u8> {
    let mut f = format!(
        "<VTKFile type=\"UnstructuredGrid\" header_type=\"UInt32\"{compressor}><UnstructuredGrid>\
         <Piece NumberOfPoints=\"{np}\" NumberOfCells=\"1\"><Points>{array}</Points></Piece></UnstructuredGrid>"
    )
    .into_bytes();
    if let Some(a) = appended {
        f.extend(b"<AppendedData encoding=\"raw\">_");
        f.extend(a);
        f.extend(b"</AppendedData>");
    }
    f.extend(b"</VTKFile>");
    f
}

fn zlib_blocks(data_len: usize, block: usize, keep: usize) -> Vec<u8> {
    let chunk = vec![0u8; block];
    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(&chunk).unwrap();
    let z = e.finish().unwrap();
    let n = data_len / block;
    let mut s: Vec<u8> = [n as u32, block as u32, 0].iter().flat_map(|w| w.to_le_bytes()).collect();
    for _ in 0..n {
        s.extend((z.len() as u32).to_le_bytes());
    }
    for _ in 0..keep.min(n) {
        s.extend(&z);
    }
    s
}

/// The most heap held while `read_vtu` reads `bytes` (from a file), above
/// what was held before, and its error.
fn peak(bytes: &[u8]) -> (u64, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.vtu");
    std::fs::write(&path, bytes).unwrap();
    let before = meter::heap_bytes_live();
    meter::reset_peak();
    let e = format!("{:#}", read_vtu(&path, None).unwrap_err());
    (meter::peak_bytes() - before, e)
}

#[test]
fn vtu_reading_holds_the_file_and_twice_its_data() {
    let mut report = Vec::new();
    for np in [1usize << 20, 1 << 22] {
        let data = 12 * np; // Float32 × 3
        let shapes = [
            // zlib: 32 KiB blocks of zeros (~0.1 % of the data).
            ("zlib", points_only(np, "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>", Some(&zlib_blocks(data, 1 << 15, usize::MAX)), " compressor=\"vtkZLibDataCompressor\"")),
            ("raw", {
                let mut a = (data as u32).to_le_bytes().to_vec();
                a.extend((0..data).map(|i| (i % 7) as u8 * 16));
                points_only(np, "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>", Some(&a), "")
            }),
            ("ascii", points_only(np, &format!("<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray>", "0 ".repeat(3 * np)), None, "")),
        ];
        for (what, file) in shapes {
            let (held, e) = peak(&file);
            assert!(e.contains("no point or numeric cell array to use as the scalar"), "{what}: {e}");
            let bar = file.len() as u64 + 2 * data as u64 + FIXED;
            report.push(format!("{what} {np} points: {held} bytes held at most, file {}, data {data}, bar {bar}", file.len()));
            assert!(held <= bar, "{}", report.join("\n"));
        }
        // Blocks promised but missing (half of them): refused before the array is allocated.
        let cut = points_only(np, "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>", Some(&zlib_blocks(data, 1 << 15, data >> 16)), " compressor=\"vtkZLibDataCompressor\"");
        let (held, e) = peak(&cut);
        assert!(e.contains("truncated the Points array"), "{e}");
        assert!(held <= cut.len() as u64 + FIXED, "truncated blocks, {np} points: {held} bytes held, file {}", cut.len());
    }
    // Issue 35's 1.5 G cells (a zlib `types` array): over the data one mesh may hold, refused from the counts.
    for nc in [1_500_000_000usize, 4_000_000_000] {
        let f = format!(
            "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkZLibDataCompressor\" header_type=\"UInt64\"><UnstructuredGrid>\
             <Piece NumberOfPoints=\"0\" NumberOfCells=\"{nc}\"><Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\"/></Points>\
             <PointData><DataArray type=\"Float32\" Name=\"s\" format=\"ascii\"/></PointData><Cells>\
             <DataArray type=\"UInt8\" Name=\"types\" format=\"binary\">AAAA</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>"
        );
        let (held, e) = peak(f.as_bytes());
        assert!(e.contains("more than the 1073741824 bytes of data one mesh may hold") || e.contains("bad NumberOfCells"), "{nc}: {e}");
        assert!(held <= FIXED, "{nc} cells: {held} bytes held");
    }
    eprintln!("{}", report.join("\n"));
}
