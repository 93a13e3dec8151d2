//! The TIN of one patch: interior points at twice the grid's density, a
//! constrained Delaunay triangulation (`spade`) of them and the patch's TB
//! vertices with every TB edge a constraint, and the faces inside the TB.

use std::collections::{HashMap, HashSet};

use anyhow::{bail, Result};
use spade::handles::{FixedFaceHandle, FixedVertexHandle, InnerTag};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation as _};

use super::geometry::{inside, segment_distance};
use super::{bilinear, world_vertex, Heightmap, Patch};

type Cdt = ConstrainedDelaunayTriangulation<Point2<f64>>;

/// Triangulate `patch`: its interior points are appended to `vertices`, its
/// triangles (indices into `vertices`; TB vertex t is vertex t) to
/// `tin_indices`.
pub(super) fn triangulate(map: &Heightmap, patch: &Patch, tb_xy: &[[f64; 2]], vertices: &mut Vec<[f32; 4]>, tin_indices: &mut Vec<u32>) -> Result<()> {
    let name = &map.name;
    let tb: Vec<u32> = (patch.tb.start..patch.tb.end).collect();
    let interior = interior_points(patch, &tb, tb_xy);
    let mut cdt = Cdt::new();
    // Our vertex index per spade vertex index.
    let mut ours: Vec<u32> = Vec::new();
    let mut handles = Vec::new();
    let mut insert = |cdt: &mut Cdt, p: [f64; 2], index: u32| -> Result<_> {
        let h = cdt.insert(Point2::new(p[0], p[1])).map_err(|e| anyhow::anyhow!("'{name}': TIN vertex {p:?}: {e:?}"))?;
        if h.index() < ours.len() {
            bail!("'{name}': patch '{}': two TIN vertices at {p:?}", patch.name);
        }
        ours.push(index);
        Ok(h)
    };
    for &t in &tb {
        handles.push(insert(&mut cdt, tb_xy[t as usize], t)?);
    }
    let first_interior = vertices.len() as u32;
    for (k, &p) in interior.iter().enumerate() {
        insert(&mut cdt, p, first_interior + k as u32)?;
        vertices.push(world_vertex(map, p, bilinear(map, p)));
    }
    for i in 0..handles.len() {
        let (a, b) = (handles[i], handles[(i + 1) % handles.len()]);
        let made = cdt.try_add_constraint(a, b);
        if made.is_empty() || !cdt.exists_constraint(a, b) {
            bail!("'{name}': patch '{}': TB edge {i} could not be a constraint edge (crossing or split)", patch.name);
        }
    }
    let inside_faces = faces_inside(&cdt, &handles);
    for face in cdt.inner_faces() {
        if inside_faces.contains(&face.fix().index()) {
            tin_indices.extend(face.vertices().map(|h| ours[h.fix().index()]));
        }
    }
    Ok(())
}

/// Points at twice the grid's density inside the patch, not within 0.2
/// cells of its TB. The TB's edges (each inside one grid cell: `boundary`
/// cuts them at every grid line) are listed by the cells within 0.2 of
/// them, so a candidate tests only its own cell's edges: time proportional
/// to the patch's area, not to area times perimeter (a 16384² grid took
/// hours).
fn interior_points(patch: &Patch, tb: &[u32], tb_xy: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut interior = Vec::new();
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in &patch.polygon {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let n = tb.len();
    let cell = |x: f64, y: f64| (x.floor() as i64, y.floor() as i64);
    let mut near: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for i in 0..n {
        let (a, b) = (tb_xy[tb[i] as usize], tb_xy[tb[(i + 1) % n] as usize]);
        let (c0, c1) = (cell(a[0].min(b[0]) - 0.2, a[1].min(b[1]) - 0.2), cell(a[0].max(b[0]) + 0.2, a[1].max(b[1]) + 0.2));
        for cx in c0.0..=c1.0 {
            for cy in c0.1..=c1.1 {
                near.entry((cx, cy)).or_default().push(i);
            }
        }
    }
    let mut y = (lo[1] * 2.0).ceil() * 0.5;
    while y < hi[1] {
        let mut x = (lo[0] * 2.0).ceil() * 0.5;
        while x < hi[0] {
            let p = [x, y];
            let edges = near.get(&cell(x, y)).map_or(&[][..], Vec::as_slice);
            if inside(&patch.polygon, p) && edges.iter().all(|&i| segment_distance(p, tb_xy[tb[i] as usize], tb_xy[tb[(i + 1) % n] as usize]) > 0.2) {
                interior.push(p);
            }
            x += 0.5;
        }
        y += 0.5;
    }
    interior
}

/// The faces inside the TB (`handles`, counter-clockwise): those left of a
/// TB edge, then everything reachable from them without crossing a
/// constraint. (A centroid test against the polygon misjudges the slivers
/// between a TB chain and the straight edge it follows.)
fn faces_inside(cdt: &Cdt, handles: &[FixedVertexHandle]) -> HashSet<usize> {
    let n = handles.len();
    let forward: HashSet<(usize, usize)> = (0..n).map(|i| (handles[i].index(), handles[(i + 1) % n].index())).collect();
    let mut inside_faces: HashSet<usize> = HashSet::new();
    let mut stack: Vec<FixedFaceHandle<InnerTag>> = Vec::new();
    for face in cdt.inner_faces() {
        if face.adjacent_edges().iter().any(|e| forward.contains(&(e.from().fix().index(), e.to().fix().index()))) && inside_faces.insert(face.fix().index()) {
            stack.push(face.fix());
        }
    }
    while let Some(f) = stack.pop() {
        for e in cdt.face(f).adjacent_edges() {
            if e.is_constraint_edge() {
                continue;
            }
            if let Some(g) = e.rev().face().fix().as_inner() {
                if inside_faces.insert(g.index()) {
                    stack.push(g);
                }
            }
        }
    }
    inside_faces
}
