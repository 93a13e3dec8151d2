//! Polyhedron cells (VTK type 42) and pentagonal / hexagonal prisms (15,
//! 16): their faces as read, checked, and split into tetrahedra.
//!
//! Faces come from the file: a `.vtu`'s old `faces` / `faceoffsets`
//! arrays or VTK 9.4+'s `face_connectivity` / `face_offsets` /
//! `polyhedron_to_faces` / `polyhedron_offsets`, or a legacy file's face
//! stream (`nfaces, n0, ids..., n1, ids...` in place of the cell's point
//! ids); a prism's faces follow from its point order.
//!
//! The split: a point at the cell's centroid (the mean of its distinct
//! vertices; scalar the mean of theirs), and every face coned to it. A
//! triangle is one tet; a quad is cut along the diagonal through its
//! smallest point id (the rule of `cells`, so a polyhedron meets a
//! hexahedron, wedge or another polyhedron on a quad face conformingly,
//! without a point); a face of five or more vertices is fanned from a point
//! at its centroid (the mean of its vertices), which the polyhedron on the
//! other side of the face reuses (keyed by the face's sorted point ids).
//!
//! Checked first, each failure an error naming the cell: every face has at
//! least three distinct points, every point is one of the cell's (for
//! `.vtu`, where the cell also lists its points), the faces close (every
//! edge on exactly two faces) and can be oriented consistently; after the
//! split, the tets around the centroid must all have one orientation (the
//! cell is star-shaped from its centroid), else the cell is refused as
//! folding over.

use std::collections::HashMap;

use anyhow::{anyhow, bail, Result};

use super::cells::quad_diagonal;
use super::geometry::tet_det;
use super::tet_builder::Tetrahedralizer;

/// VTK cell types split here.
pub const VTK_PENTAGONAL_PRISM: u8 = 15;
pub const VTK_HEXAGONAL_PRISM: u8 = 16;
pub const VTK_POLYHEDRON: u8 = 42;

/// Parses one cell's VTK face stream (`nfaces, n0, ids..., n1, ids...`),
/// which must use exactly `stream`; every id below `np`.
pub fn parse_face_stream(stream: &[i64], np: usize) -> Result<Vec<Vec<u32>>> {
    let nf = *stream.first().ok_or_else(|| anyhow!("its face stream is empty"))?;
    if nf < 4 || nf as u64 > stream.len() as u64 {
        bail!("its face stream declares {nf} faces in {} values (a polyhedron has at least 4 faces)", stream.len());
    }
    let mut faces = Vec::with_capacity(nf as usize);
    let mut i = 1usize;
    for f in 0..nf as usize {
        let k = *stream.get(i).ok_or_else(|| anyhow!("its face stream ends before face {f} of {nf}"))?;
        if k < 3 || k as u64 > (stream.len() - i - 1) as u64 {
            bail!("face {f} of its face stream claims {k} points, {} values remain", stream.len() - i - 1);
        }
        let ids = &stream[i + 1..i + 1 + k as usize];
        if let Some(&bad) = ids.iter().find(|&&v| v < 0 || v as u64 >= np as u64) {
            bail!("face {f} has point index {bad} out of range (the file has {np} points)");
        }
        faces.push(ids.iter().map(|&v| v as u32).collect());
        i += 1 + k as usize;
    }
    if i != stream.len() {
        bail!("its face stream holds {} values but its {nf} faces use {i}", stream.len());
    }
    Ok(faces)
}

/// The faces of a pentagonal (10 points) or hexagonal (12) prism.
pub fn prism_faces(v: &[u32]) -> Vec<Vec<u32>> {
    let n = v.len() / 2;
    let mut faces = vec![v[..n].iter().rev().copied().collect::<Vec<u32>>(), v[n..].to_vec()];
    for i in 0..n {
        let j = (i + 1) % n;
        faces.push(vec![v[i], v[j], v[n + j], v[n + i]]);
    }
    faces
}

/// Checks and splits one polyhedron (module docs). `points`, when the file
/// lists the cell's points besides its faces, must hold every face point.
pub(crate) fn split(tz: &mut Tetrahedralizer, faces: &[&[u32]], points: Option<&[u32]>) -> Result<()> {
    if faces.len() < 4 {
        bail!("has {} faces; a polyhedron has at least 4", faces.len());
    }
    let mut fs: Vec<Vec<u32>> = Vec::with_capacity(faces.len());
    for (i, f) in faces.iter().enumerate() {
        fs.push(simple_face(i, f, points)?);
    }
    let edges = closed_edges(&fs)?;
    orient_faces(&mut fs, &edges)?;
    let c = add_centroid(tz, &fs)?;
    let tris = cone_triangles(tz, &fs)?;
    let tets: Vec<[u32; 4]> = tris.iter().map(|t| [t[0], t[1], t[2], c]).collect();
    add_cone(tz, tets)?;
    tz.stats.polyhedra += 1;
    Ok(())
}

/// Face `i` (`f`) as a point list, consecutive repeats (collapsed edges)
/// removed; checked to be a simple loop of three or more points, each one
/// of the cell's `points` when the file lists them.
fn simple_face(i: usize, f: &[u32], points: Option<&[u32]>) -> Result<Vec<u32>> {
    let mut g: Vec<u32> = Vec::with_capacity(f.len());
    for &v in f.iter() {
        if g.last() != Some(&v) {
            g.push(v);
        }
    }
    while g.len() > 1 && g.first() == g.last() {
        g.pop();
    }
    let mut s = g.clone();
    s.sort_unstable();
    s.dedup();
    if s.len() != g.len() || g.len() < 3 {
        bail!("face {i} {:?} does not have three or more distinct points in a simple loop", f);
    }
    if let Some(p) = points {
        if let Some(v) = g.iter().find(|v| !p.contains(v)) {
            bail!("face {i} names point {v}, which is not among the cell's {} points", p.len());
        }
    }
    Ok(g)
}

/// The faces each edge (its ids low, high) is on; an error unless the
/// faces close (every edge on exactly two faces).
fn closed_edges(fs: &[Vec<u32>]) -> Result<HashMap<(u32, u32), Vec<usize>>> {
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, f) in fs.iter().enumerate() {
        for k in 0..f.len() {
            let (a, b) = (f[k], f[(k + 1) % f.len()]);
            edges.entry((a.min(b), a.max(b))).or_default().push(i);
        }
    }
    let mut open: Vec<_> = edges.iter().filter(|(_, v)| v.len() != 2).collect();
    open.sort();
    if let Some(((a, b), holders)) = open.first() {
        bail!("its faces do not close: the edge {a}-{b} is on {} face(s), not 2", holders.len());
    }
    Ok(edges)
}

/// Orients the faces consistently (a face crosses each shared edge the
/// other way from its neighbour), reversing those that need it.
fn orient_faces(fs: &mut [Vec<u32>], edges: &HashMap<(u32, u32), Vec<usize>>) -> Result<()> {
    let mut flip: Vec<Option<bool>> = vec![None; fs.len()];
    for start in 0..fs.len() {
        if flip[start].is_some() {
            continue;
        }
        flip[start] = Some(false);
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            orient_neighbours(fs, edges, &mut flip, i, &mut stack)?;
        }
    }
    for (i, f) in fs.iter_mut().enumerate() {
        if flip[i] == Some(true) {
            f.reverse();
        }
    }
    Ok(())
}

/// One step of [`orient_faces`]' walk: the flips of face `i`'s
/// neighbours from its own, the newly decided ones pushed to `stack`.
fn orient_neighbours(
    fs: &[Vec<u32>],
    edges: &HashMap<(u32, u32), Vec<usize>>,
    flip: &mut [Option<bool>],
    i: usize,
    stack: &mut Vec<usize>,
) -> Result<()> {
    let directed = |f: &Vec<u32>, a: u32, b: u32| (0..f.len()).any(|k| f[k] == a && f[(k + 1) % f.len()] == b);
    let fi: Vec<u32> = if flip[i] == Some(true) { fs[i].iter().rev().copied().collect() } else { fs[i].clone() };
    for k in 0..fi.len() {
        let (a, b) = (fi[k], fi[(k + 1) % fi.len()]);
        for &j in &edges[&(a.min(b), a.max(b))] {
            if j == i {
                continue;
            }
            // j must run b -> a.
            let want = !directed(&fs[j], b, a);
            match flip[j] {
                None => {
                    flip[j] = Some(want);
                    stack.push(j);
                }
                Some(x) if x != want => bail!("its faces cannot be oriented consistently (at the edge {a}-{b})"),
                _ => {}
            }
        }
    }
    Ok(())
}

/// Adds the cell's centroid point (the mean of its distinct points and of
/// their values); its index.
fn add_centroid(tz: &mut Tetrahedralizer, fs: &[Vec<u32>]) -> Result<u32> {
    let mut distinct: Vec<u32> = fs.iter().flatten().copied().collect();
    distinct.sort_unstable();
    distinct.dedup();
    let w = 1.0 / distinct.len() as f64;
    let terms: Vec<(u32, f64)> = distinct.iter().map(|&v| (v, w)).collect();
    let (pos, val) = tz.combine(&terms);
    tz.add_point(pos, val)
}

/// The faces as triangles: a quad cut by the min-index rule, a face of
/// five or more points fanned from its (shared) centre point.
fn cone_triangles(tz: &mut Tetrahedralizer, fs: &[Vec<u32>]) -> Result<Vec<[u32; 3]>> {
    let mut tris: Vec<[u32; 3]> = Vec::new();
    for f in fs {
        match f.len() {
            3 => tris.push([f[0], f[1], f[2]]),
            4 => {
                if quad_diagonal(&[0, 1, 2, 3], f) == 0 {
                    tris.extend([[f[0], f[1], f[2]], [f[0], f[2], f[3]]]);
                } else {
                    tris.extend([[f[0], f[1], f[3]], [f[1], f[2], f[3]]]);
                }
            }
            n => {
                let mut key = f.clone();
                key.sort_unstable();
                let w = 1.0 / n as f64;
                let terms: Vec<(u32, f64)> = f.iter().map(|&v| (v, w)).collect();
                let m = tz.face_point(key, &terms)?;
                for k in 0..n {
                    tris.push([f[k], f[(k + 1) % n], m]);
                }
            }
        }
    }
    Ok(tris)
}

/// Adds the tets of the cone, positively oriented; an error when they do
/// not all have one orientation (the cell is not star-shaped from its
/// centroid) or have no volume.
fn add_cone(tz: &mut Tetrahedralizer, tets: Vec<[u32; 4]>) -> Result<()> {
    let dets: Vec<(f64, bool)> = tets.iter().map(|t| tet_det(t.map(|v| tz.points[v as usize]))).collect();
    let net: f64 = dets.iter().map(|d| d.0).sum();
    let folds = dets.iter().any(|&(d, flat)| !flat && (d > 0.0) != (net > 0.0));
    if folds || net == 0.0 {
        bail!("folds over: it is not star-shaped from its centroid (or has no volume), so the tetrahedra around it would overlap");
    }
    // Outward faces make the cone negative: emit positively oriented tets.
    for mut t in tets {
        if net < 0.0 {
            t.swap(0, 1);
        }
        tz.tets.push(t);
    }
    Ok(())
}
