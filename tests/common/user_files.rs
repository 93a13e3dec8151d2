//! Small users' files written as a user's program would (ASCII VTK XML):
//! for `suite --data FILE` (tests/suitedata.rs) and the peers' side of it
//! (tests/peers.rs).

use std::path::Path;

/// A 3x3x3-point grid of 8 hexahedra (ASCII `.vtu`): point arrays `temp`
/// (smooth) and `velocity` (3 components), `temp` the active scalars.
pub fn write_vtu(path: &Path) {
    let mut points = Vec::new();
    let (mut temp, mut vel) = (Vec::new(), Vec::new());
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..3 {
                let (x, y, z) = (i as f64, j as f64 * 0.8, k as f64 * 1.2);
                points.push(format!("{x} {y} {z}"));
                temp.push(format!("{}", 1.0 + x + 0.5 * y * y + 0.25 * z));
                vel.push(format!("{} {} {}", y, 1.0 - x, 0.5 * z));
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| i + 3 * j + 9 * k;
    let mut conn = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                let c = [
                    id(i, j, k),
                    id(i + 1, j, k),
                    id(i + 1, j + 1, k),
                    id(i, j + 1, k),
                    id(i, j, k + 1),
                    id(i + 1, j, k + 1),
                    id(i + 1, j + 1, k + 1),
                    id(i, j + 1, k + 1),
                ];
                conn.push(c.map(|v| v.to_string()).join(" "));
            }
        }
    }
    let offsets: Vec<String> = (1..=8).map(|c| (8 * c).to_string()).collect();
    let text = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"27\" NumberOfCells=\"8\">\n<PointData Scalars=\"temp\">\n\
         <DataArray type=\"Float64\" Name=\"temp\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray>\n</PointData>\n\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></Points>\n\
         <Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
        temp.join(" "),
        vel.join(" "),
        points.join(" "),
        conn.join(" "),
        offsets.join(" "),
        ["12"; 8].join(" ")
    );
    std::fs::write(path, text).unwrap();
}

/// A 10x8x6 Float32 volume (ASCII `.vti`): a blob, spacing and origin not 1 and 0.
pub fn write_vti(path: &Path) {
    let mut v = Vec::new();
    for k in 0..6 {
        for j in 0..8 {
            for i in 0..10 {
                let (x, y, z) = (i as f64 - 4.5, j as f64 - 3.5, k as f64 - 2.5);
                v.push(format!("{:.4}", 100.0 * (-(x * x + y * y + z * z) / 12.0).exp()));
            }
        }
    }
    let text = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\">\n\
         <ImageData WholeExtent=\"0 9 0 7 0 5\" Origin=\"-1 2 0.5\" Spacing=\"0.5 0.5 0.75\">\n<Piece Extent=\"0 9 0 7 0 5\">\n\
         <PointData Scalars=\"density\"><DataArray type=\"Float32\" Name=\"density\" format=\"ascii\">{}</DataArray></PointData>\n\
         </Piece>\n</ImageData>\n</VTKFile>\n",
        v.join(" ")
    );
    std::fs::write(path, text).unwrap();
}
