//! Face adjacency of a tetrahedral mesh, built once per render.
//!
//! Faces are matched by their sorted vertex triple (a parallel sort of all
//! `4·n` faces, then a scan of equal runs): a triple held by exactly two tets
//! links them; a triple held by one tet is a boundary face. A triple held by
//! three or more tets (a non-manifold, invalid mesh) leaves all of them as
//! boundary faces and is counted. Tets with a repeated vertex index carry no
//! volume and no usable faces: they are left out entirely (their would-be
//! neighbours pair with each other or become boundary).

use rayon::prelude::*;

use crate::mesh::TetMesh;

/// `neighbor` value of a boundary face.
pub(crate) const NONE: u32 = u32::MAX;

/// Local vertex indices of face `f` (the face opposite vertex `f`), ordered
/// counter-clockwise seen from outside a positively oriented tet, i.e. the
/// normal `(v1 − v0) × (v2 − v0)` points out of the tet.
pub(crate) const FACE_VERTS: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

pub(crate) struct Topology {
    /// `neighbor[4·t + f]` = `4·t' + f'`: face `f` of tet `t` is face `f'` of
    /// tet `t'`; `NONE` on the boundary.
    pub neighbor: Vec<u32>,
    /// Boundary faces as `4·t + f`.
    pub boundary: Vec<u32>,
    /// Faces shared by three or more tets (invalid input), left as boundary.
    pub non_manifold_faces: usize,
    /// Tets left out because a vertex index repeats.
    pub collapsed_tets: usize,
    /// Per tet: positive volume beyond rounding, `det[p1−p0, p2−p0, p3−p0] >
    /// 1e-12·L³` (L: longest edge from p0). Flat cells (zero or negligible
    /// volume, or inverted) are `false`: the walk ignores their orientation.
    pub solid: Vec<bool>,
}

/// Relative volume below which a cell counts as flat (see `Topology::solid`).
const FLAT_REL: f64 = 1e-12;

fn is_solid(p: &[[f64; 3]], t: &[u32; 4]) -> bool {
    let p0 = p[t[0] as usize];
    let e = |k: usize| {
        let q = p[t[k] as usize];
        [q[0] - p0[0], q[1] - p0[1], q[2] - p0[2]]
    };
    let (a, b, c) = (e(1), e(2), e(3));
    let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]);
    let l2 = [a, b, c]
        .iter()
        .map(|v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        .fold(0.0, f64::max);
    det > FLAT_REL * l2 * l2.sqrt()
}

impl Topology {
    pub fn build(mesh: &TetMesh) -> Topology {
        let n = mesh.tets.len();
        let collapsed = |t: &[u32; 4]| {
            t[0] == t[1]
                || t[0] == t[2]
                || t[0] == t[3]
                || t[1] == t[2]
                || t[1] == t[3]
                || t[2] == t[3]
        };
        let mut faces: Vec<(u64, u32, u32)> = mesh
            .tets
            .par_iter()
            .enumerate()
            .filter(|(_, t)| !collapsed(t))
            .flat_map_iter(|(ti, t)| {
                (0..4).map(move |f| {
                    let mut k = [
                        t[FACE_VERTS[f][0]],
                        t[FACE_VERTS[f][1]],
                        t[FACE_VERTS[f][2]],
                    ];
                    k.sort_unstable();
                    (
                        ((k[0] as u64) << 32) | k[1] as u64,
                        k[2],
                        (4 * ti + f) as u32,
                    )
                })
            })
            .collect();
        faces.par_sort_unstable();
        let collapsed_tets = n - faces.len() / 4;
        let mut neighbor = vec![NONE; 4 * n];
        let mut boundary = Vec::new();
        let mut non_manifold_faces = 0;
        let mut i = 0;
        while i < faces.len() {
            let key = (faces[i].0, faces[i].1);
            let mut j = i + 1;
            while j < faces.len() && (faces[j].0, faces[j].1) == key {
                j += 1;
            }
            match j - i {
                1 => boundary.push(faces[i].2),
                2 => {
                    let (a, b) = (faces[i].2, faces[i + 1].2);
                    neighbor[a as usize] = b;
                    neighbor[b as usize] = a;
                }
                _ => {
                    non_manifold_faces += j - i;
                    boundary.extend(faces[i..j].iter().map(|f| f.2));
                }
            }
            i = j;
        }
        boundary.sort_unstable();
        let solid = mesh
            .tets
            .par_iter()
            .map(|t| is_solid(&mesh.points, t))
            .collect();
        Topology {
            neighbor,
            boundary,
            non_manifold_faces,
            collapsed_tets,
            solid,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    #[test]
    fn face_orders_point_outwards() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.2, 0.3, 1.0],
        ];
        assert!(dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), sub(p[3], p[0])) > 0.0);
        for (f, fv) in FACE_VERTS.iter().enumerate() {
            assert!(!fv.contains(&f));
            let n = cross(sub(p[fv[1]], p[fv[0]]), sub(p[fv[2]], p[fv[0]]));
            assert!(dot(n, sub(p[f], p[fv[0]])) < 0.0, "face {f}");
        }
    }

    #[test]
    fn two_tets_share_one_face() {
        let mesh = TetMesh {
            name: "two".into(),
            points: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
            ],
            scalars: vec![0.0; 5],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4], [1, 1, 2, 3]],
            stats: Default::default(),
        };
        let t = Topology::build(&mesh);
        assert_eq!(t.neighbor[0], 4 + 3); // face 0 of tet 0 = (1,2,3) = face 3 of tet 1
        assert_eq!(t.neighbor[4 + 3], 0);
        assert_eq!(t.boundary.len(), 6);
        assert_eq!(t.collapsed_tets, 1);
        assert_eq!(t.non_manifold_faces, 0);
        assert_eq!(t.solid, vec![true, true, false]); // tet 2 is collapsed
    }
}
