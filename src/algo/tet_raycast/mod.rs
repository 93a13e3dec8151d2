//! `tet-raycast`: hardware-based ray casting of tetrahedral meshes (Weiler,
//! Kraus, Merz, Ertl, Vis 2003) as one compute pass (`shaders/tet_raycast/
//! walk.comp`), beyond the thesis (issue 12). Each pixel's ray finds the
//! first boundary face it enters, walks cell to cell through face adjacency,
//! integrating each segment with the integrator the cell-projection methods
//! use (`shaders/common/integrate.glsl`, the same tables), and after leaving
//! the mesh continues at the next boundary face it enters (non-convex meshes,
//! the oxygen post's unmerged seam). No sort and no per-frame cell data: the
//! mesh (points with scalars, cells, face adjacency, which cells are solid)
//! and a BVH over the boundary faces are uploaded once; per frame the camera
//! crosses (push constants) and, when the search uses them, the boundary
//! faces listed per screen tile ([`tiles`]: 4 bytes per tile and per entry).
//!
//! **Only the pixels that may meet the mesh run** (issue 24): the dispatch
//! covers the boundary's projected rectangle ([`pixel_rect`]) and the rest of
//! the image is cleared. On llvmpipe an invocation that returns at once
//! still runs its whole shader masked, so the 190 k pixels outside
//! post-small's rectangle cost 13 ms a frame before (docs/compute-speed.md).
//!
//! **Same walk as the f64 reference.** The adjacency is the reference's
//! ([`Topology`]: `mesh::adjacency` by vertex index, cells with a repeated
//! index left out, faces of three or more cells treated as boundary) and so
//! is the crossing rule (Plücker edge values with canonical orientation and
//! a symbolic perturbation; flat cells crossed whichever way they are
//! oriented, with zero-length segments). Boundary entries are taken in
//! (depth, face) order along the whole ray line, as the reference takes
//! them, so the eye may be inside the mesh: the walk then starts behind the
//! eye and integrates from the near plane on (not required by issue 12; it
//! costs the cells behind the eye).
//!
//! **Entry search: per-tile face lists, else a BVH.** When every boundary
//! vertex is in front of the eye (or the view is orthographic) the boundary
//! faces that face the eye are binned per frame into tiles of 8x1 pixels
//! ([`tiles`]) and a ray's searches test its tile's faces. Otherwise a ray's
//! line may meet the mesh behind the eye as well, and the search walks a BVH
//! over the boundary faces, built once on the CPU (median split on the
//! longest centroid axis, up to [`LEAF_FACES`] faces per leaf), nearest child
//! first. Both return the least entry (t, face) after the previous one, so
//! they find the same entries (tested); on llvmpipe a BVH step costs a
//! node-pair test and a face test whatever a lane needs, about twice a cell
//! step, so the lists cut the searches' cost by more than half.
//!
//! **No search after leaving through the hull.** A ray that leaves the mesh
//! through a boundary face on its convex hull ([`hull_faces`], marked once)
//! meets no more of it: the walk ends there without the search that would
//! find nothing.
//!
//! **Bounded walks.** A ray visits at most (cells + [`STEP_MARGIN`]) cells
//! over all its walks, and a walk that makes no progress in depth for
//! [`STALL_LIMIT`] consecutive cells is abandoned (the reference's limits,
//! with its step budget cut to one pass over the mesh plus a margin): the
//! blunt fin's 77 zero-volume cells cannot hang a ray. Rays that hit the
//! budget and stalled walks are counted and reported, as are exits chosen by
//! the fallback rule (rounding) and walks stopped going backwards.
//!
//! **Early ray termination** (`ert`, default [`ERT_DEFAULT`]): a ray stops
//! once its opacity reaches the threshold. What it drops is at most its
//! remaining transmittance times the (≤ 1) colour of what lies behind, so
//! the error per channel grows by at most 1 − ert (1e-3 at the default);
//! `ert=1` stops only when the transmittance is exactly 0 in f32.
//!
//! **Counts** (device counters, read back after every frame, deterministic):
//! cells visited (total, max per ray), rays that entered the mesh, rays that
//! re-entered it, rays terminated early, walk-bound hits, stalled walks,
//! fallback exits, reversed walks, entry searches, BVH nodes visited and
//! boundary faces tested by them; per frame the tile lists' entries.

mod silhouette;
mod tiles;

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use serde_json::json;

use super::settings::{choice, float, int, MethodSettings};
use super::tet_mesh::{integrator_bound, render_origin, scalar_map, MeshScale, INTEGRATOR_HELP, TABLE_SIZE_HELP};
use super::chunks::{ensure_frame_texels, frame_texels, ChunkLimits, TexelChunks};
use tiles::{Projected, TileLists, TILE};
use super::host_memory::HostMemory;
use super::screen;
use super::adaptive::{Adaptive, Silhouettes};
use silhouette::BoundaryEdges;
use super::integrate::{check_table_size, IntegrationTables, Integrator, TableMap};
use super::method::{DataKind, Family, MethodInfo, MethodInputs, OptionSpec, Options, Phases, RenderMethod, SceneData, View, Work};
use crate::mesh::adjacency::FACE_VERTS;
use crate::mesh::TetMesh;
use crate::mesh::topology::Topology;
use crate::scene::Camera;
use crate::vk::{
    Buffer, BufferDesc, CommandRecorder, ComputePipelineKey, Context, DescriptorKind, DescriptorResource,
    DescriptorSet, DescriptorSetDesc, Image, Pipeline, PipelineKey, ShaderKey, ShaderStage, TargetImageSet, TexelBuffer, UploadClass,
    UploadCounter,
};
use crate::vk::{Format, Stages};

/// Workgroup shape (pixels).
pub const WORKGROUP: [u32; 2] = [8, 8];
/// Largest number of boundary faces in a BVH leaf.
pub const LEAF_FACES: usize = 4;
/// Cells a ray may visit beyond one pass over the mesh.
pub const STEP_MARGIN: u64 = 1024;
/// Consecutive cells without progress in depth that abandon a walk.
pub const STALL_LIMIT: u32 = 1024;
/// The default early-termination opacity.
pub const ERT_DEFAULT: f64 = 0.999;
/// The walk's push constants (`shaders/tet_raycast/frame.glsl`, `Frame`;
/// `tests/shader_interfaces.rs` checks the two agree).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct WalkFrame {
    /// The eye, relative to the render origin.
    pub eye: glam::Vec3,
    /// 1 perspective, 0 orthographic.
    pub perspective: f32,
    /// Unit view direction.
    pub forward: glam::Vec3,
    /// Near plane (view depth).
    pub near: f32,
    /// Right, scaled so that ndc x = 1 is the image's edge (`Camera::image_axes`).
    pub right: glam::Vec3,
    /// Far plane (view depth).
    pub far: f32,
    /// Up, scaled alike.
    pub up: glam::Vec3,
    /// Early-termination opacity (>= 1: off).
    pub ert: f32,
    pub table: TableMap,
    /// Entry tolerance (world units).
    pub entry_tol: f32,
    /// Cells a ray may visit ([`STEP_MARGIN`] past one pass over the mesh).
    pub step_budget: u32,
    /// [`STALL_LIMIT`].
    pub stall_limit: u32,
    /// The pixels whose rays may meet the mesh ([`pixel_rect`]): x0, y0, x1,
    /// y1 inclusive; the dispatch starts at x0, y0.
    pub rect: [u32; 4],
    /// Rows of workgroups and the device's runs (`common/dispatch.glsl`,
    /// `interleaved_row`).
    pub rows: u32,
    pub runs: u32,
    /// Adaptive refinement's cast step (8, 4, 2 or 1; 0 without).
    pub cast_step: u32,
}

/// The size of [`WalkFrame`], as the pipelines' push-constant range.
const PUSH_BYTES: u32 = std::mem::size_of::<WalkFrame>() as u32;
/// Pixels added around the boundary's projected box before pixels outside
/// it are skipped (covers the f32 rounding of the shader's rays).
const RECT_PAD: f64 = 2.0;
/// The top bit of a cell's fourth vertex index and of a boundary face's
/// slot: the cell is solid (`SOLID_BIT` in walk.comp).
const SOLID_BIT: u32 = 1 << 31;
/// Pixels a face's projection is padded by when it is binned into tiles
/// ([`tiles`]): the shader's f32 rays and the f64 projection differ by
/// far less (~1e-4 pixel at 512x512).
const TILE_PAD: f64 = 0.25;
/// Pixels a silhouette edge is padded by when adaptive refinement marks the
/// blocks it reaches (`algo::adaptive::Silhouettes`): the shader's f32 rays
/// and the f64 projection differ by ~1e-4 pixel at 512x512 (`TILE_PAD`).
const SILHOUETTE_PAD: f64 = 0.01;

/// The neighbour of a boundary face the ray may meet the mesh again after
/// (`REENTER` in walk.comp); a boundary face on the convex hull keeps
/// `topology::NONE`, and the walk ends there ([`hull_faces`]).
const REENTER: u32 = 0xFFFF_FFFE;

/// Counter words read back after every frame (`Counters` in walk.comp).
const COUNTER_WORDS: usize = 14;
/// Bits of a BVH stack entry below the node's link, holding its face count
/// (`LINK_SHIFT` in walk.comp).
const LINK_SHIFT: u32 = 3;
const _: () = assert!(LEAF_FACES < 1 << LINK_SHIFT);
/// The BVH's depth bound the shader's traversal stack holds (48 entries).
const MAX_BVH_DEPTH: usize = 40;

crate::choices! {
    /// How a ray finds the boundary face it enters.
    #[derive(Default)]
    pub enum Search {
        /// The faces listed for its screen tile ([`tiles`]) when every
        /// boundary vertex is in front of the eye or the view is
        /// orthographic, else the BVH.
        #[default]
        Auto = "auto",
        /// The BVH over the boundary faces, always (the same entries).
        Bvh = "bvh",
    }
}

crate::settings! {
    /// Integrator and table size as the cell-projection methods take them,
    /// the termination threshold and the entry search.
    pub struct Settings {
        integrator: Integrator = "ppi", choice::<Integrator>(), build, "", INTEGRATOR_HELP;
        table_size: usize = "0", int(0, 4096), run, "samples per side", TABLE_SIZE_HELP;
        ert: f64 = "0.999", float(0.5, 1.0), run, "opacity",
            "early ray termination: stop once the ray's opacity reaches this (1 = only when fully opaque); \
             adds at most 1 - ert to a pixel's error";
        search: Search = "auto", choice::<Search>(), run, "",
            "how a ray finds the boundary face it enters: auto (the faces binned per frame into its 8x1-pixel tile \
             when every boundary vertex is in front of the eye or the view is orthographic, else the BVH) or bvh \
             (always the BVH over the boundary faces); both find the same entries";
        adaptive: f64 = "0", float(0.0, 0.25), build, "TOL", crate::algo::adaptive::HELP;
    }
    impl {
        fn check(&self) -> Result<()> {
            check_table_size(self.integrator, self.table_size)
        }
    }
}

pub const OPTIONS: &[OptionSpec] = Settings::OPTIONS;

/// What the walk is compiled for beside the settings: facts of the mesh
/// and of how it lies on the device.
struct WalkFacts {
    /// Constant cells (`mesh::cell_data`): each tet has its own copies of
    /// the points; the walk renames the carried face to the next cell's
    /// copies and takes that cell's value (walk.comp, CELL_CONSTANT).
    cell_constant: bool,
    /// How the points and per-cell arrays are split (`algo::chunks`).
    chunks: Vec<(String, String)>,
}

/// The descriptor-set layouts the walk binds, in set order: the tables,
/// the mesh, the target, and the tile lists when it searches them.
struct WalkSets {
    tables: DescriptorSetDesc,
    mesh: DescriptorSetDesc,
    target: DescriptorSetDesc,
    lists: DescriptorSetDesc,
}

impl Settings {
    /// The build-time options as the walk's defines (`walk_defines` adds
    /// the mesh's facts and the variant's).
    fn defines(&self) -> Vec<(&'static str, &'static str)> {
        self.integrator.define().into_iter().collect()
    }

    /// The walk's shader defines, the one place they are made: the
    /// build-time options, the workgroup, the mesh's facts, then the
    /// variant's: the per-tile face lists (`lists`) and adaptive refinement
    /// (its set's index).
    fn walk_defines(&self, facts: &WalkFacts, lists: bool, adaptive_set: Option<usize>) -> Vec<(String, String)> {
        let owned = |(k, v): (&str, &str)| (k.to_string(), v.to_string());
        let mut d: Vec<(String, String)> = self.defines().into_iter().map(owned).collect();
        d.push(("WG_X".into(), WORKGROUP[0].to_string()));
        d.push(("WG_Y".into(), WORKGROUP[1].to_string()));
        if facts.cell_constant {
            d.push(owned(("CELL_CONSTANT", "1")));
        }
        d.extend(facts.chunks.iter().cloned());
        if lists {
            d.extend([owned(("TILE_LISTS", "1")), ("TILE_W".into(), TILE[0].to_string()), ("TILE_H".into(), TILE[1].to_string())]);
        }
        if let Some(set) = adaptive_set {
            d.extend([owned(("ADAPTIVE", "1")), ("ADAPTIVE_SET".into(), set.to_string())]);
        }
        d
    }

    /// The key of the walk's variant: searching the tile lists (set 3) or
    /// the BVH, and with adaptive refinement's set (`adaptive`) after the
    /// others.
    fn walk_key(&self, facts: &WalkFacts, sets: &WalkSets, lists: bool, adaptive: Option<&DescriptorSetDesc>) -> PipelineKey {
        let mut descs = vec![sets.tables.clone(), sets.mesh.clone(), sets.target.clone()];
        if lists {
            descs.push(sets.lists.clone());
        }
        let adaptive_set = adaptive.map(|_| descs.len());
        descs.extend(adaptive.cloned());
        let defines = self.walk_defines(facts, lists, adaptive_set);
        let defines: Vec<(&str, &str)> = defines.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        PipelineKey::Compute(ComputePipelineKey {
            shader: ShaderKey::new("tet_raycast/walk.comp", ShaderStage::Compute, &defines),
            push_constant_bytes: PUSH_BYTES,
            sets: descs,
        })
    }
}

pub const METHOD: MethodInfo = MethodInfo {
    name: "tet-raycast",
    data: DataKind::TetMesh,
    summary: "tetrahedral ray casting in compute (Weiler et al. 2003): entry through per-tile boundary-face lists \
              (else a BVH), cell-to-cell walk through face adjacency, re-entry; the camera and the tile lists per frame",
    options: OPTIONS,
    features: &[],
    sweep: &[
        "integrator=average",
        "integrator=preint,table_size=128",
        "integrator=ppi,table_size=128",
        "integrator=ppi,table_size=512",
        "integrator=ppi,table_size=1024",
        "integrator=linear-exact",
        "integrator=ppi,ert=0.99",
        "integrator=ppi,ert=1",
        "adaptive=0.008",
        "adaptive=0.016",
        "adaptive=0.032",
        "adaptive=0.064",
        "adaptive=0.128",
    ],
    compare: &["", "ert=1"],
    stress: &["integrator=average", "integrator=preint", "integrator=ppi", "integrator=linear-exact", "integrator=ppi,adaptive=0.008"],
    // Adaptive refinement at three tolerances (about 4/255, 12/255 and
    // 33/255; the biquadratic fills keep the error well below them), the
    // same on every mesh: a front against time, not one point.
    suite: &["adaptive=0.016", "adaptive=0.048", "adaptive=0.128"],
    published: &[],
    family: Family {
        name: "tet-raycast",
        check: crate::algo::settings::check::<Settings>,
        accuracy_bound,
        culling_option: None,
        placement: None,
        camera: |_, _| None,
    },
    create,
};

/// The cell-projection bound of the integrator with exact interpolation
/// (the segments are exact along each ray, as that interpolation's are),
/// plus what early termination may drop (1 - ert), plus twice the adaptive
/// tolerance ([`crate::algo::adaptive::bound`]).
pub fn accuracy_bound(options: &Options, _perspective: bool) -> Option<f64> {
    let s = Settings::from_options(options).ok()?;
    Some(integrator_bound(s.integrator) + (1.0 - s.ert).max(0.0) + crate::algo::adaptive::bound(s.adaptive))
}

/// The pixels whose rays may meet the mesh: the box of the boundary
/// vertices' projections (a ray enters only through a boundary face, which
/// projects inside its vertices' box), padded by [`RECT_PAD`], as inclusive
/// pixel bounds `[x0, y0, x1, y1]` (x0 > x1: no pixel). `None` when every
/// pixel must search: in perspective some boundary vertices at or behind the
/// eye plane and some in front of it (the shader searches the whole ray line,
/// behind the eye too), or a projection that is not finite. In perspective
/// with every boundary vertex at or behind the eye plane no pixel: the mesh
/// lies in their hull, behind the eye, and a ray integrates only from the
/// near plane on (the camera turned away). `right`, `up` are the camera's image axes
/// (`Camera::image_axes`: perpendicular to `forward`, scaled so that ndc 1
/// is the image's edge), `points` relative to the eye.
pub fn pixel_rect(points: &[[f64; 3]], forward: [f64; 3], right: [f64; 3], up: [f64; 3], perspective: bool, width: u32, height: u32) -> Option<[u32; 4]> {
    let view = tiles::View { eye: [0.0; 3], forward, right, up, perspective, size: [width, height] };
    rect_of(&view.project(points), [width, height])
}

/// The workgroups dispatched over the inclusive pixel bounds `rect`, from
/// its corner (walk.comp adds it).
fn rect_groups([x0, y0, x1, y1]: [u32; 4]) -> [u32; 3] {
    if x0 > x1 || y0 > y1 {
        return [0, 0, 1];
    }
    [(x1 - x0 + 1).div_ceil(WORKGROUP[0]), (y1 - y0 + 1).div_ceil(WORKGROUP[1]), 1]
}

/// [`pixel_rect`] from the points' projection, made once per frame for the
/// rectangle and the tile lists.
fn rect_of(projected: &Projected, size: [u32; 2]) -> Option<[u32; 4]> {
    let px = match projected {
        Projected::Pixels(px) => px,
        Projected::NoneInFront => return Some(crate::algo::screen::NO_PIXELS),
        Projected::Unplaced => return None,
    };
    Some(crate::algo::screen::pixel_bounds(px.iter().copied(), RECT_PAD, size))
}

/// A BVH over boundary faces, as the shader reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct FaceBvh {
    /// Per node: box min (w: left child or first primitive, u32 bits), box
    /// max (w: 0 for an inner node, else the primitive count, u32 bits).
    pub nodes: Vec<[f32; 8]>,
    /// Face slots `4 c + f`, in leaf order.
    pub prims: Vec<u32>,
    pub depth: usize,
}

/// Builds the BVH of `faces` (slot, three vertex positions), each box
/// padded by `pad`. Deterministic: ties in the median split are broken by
/// slot. An empty input gives one node that no ray enters.
pub fn build_face_bvh(faces: &[(u32, [[f32; 3]; 3])], pad: f32) -> FaceBvh {
    struct Item {
        slot: u32,
        centroid: [f32; 3],
        lo: [f32; 3],
        hi: [f32; 3],
    }
    let mut items: Vec<Item> = faces
        .iter()
        .map(|&(slot, p)| {
            let lo = std::array::from_fn(|k| p[0][k].min(p[1][k]).min(p[2][k]) - pad);
            let hi = std::array::from_fn(|k| p[0][k].max(p[1][k]).max(p[2][k]) + pad);
            let centroid = std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
            Item { slot, centroid, lo, hi }
        })
        .collect();
    let bits = |v: u32| f32::from_bits(v);
    if items.is_empty() {
        let e = 1e30f32;
        return FaceBvh { nodes: vec![[e, e, e, bits(0), -e, -e, -e, bits(0)]], prims: Vec::new(), depth: 1 };
    }
    let mut nodes: Vec<[f32; 8]> = vec![[0.0; 8]];
    let mut depth = 1;
    // (node, start, end, level)
    let mut stack = vec![(0usize, 0usize, items.len(), 1usize)];
    while let Some((node, start, end, level)) = stack.pop() {
        depth = depth.max(level);
        let range = &mut items[start..end];
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut clo = [f32::INFINITY; 3];
        let mut chi = [f32::NEG_INFINITY; 3];
        for it in range.iter() {
            for k in 0..3 {
                lo[k] = lo[k].min(it.lo[k]);
                hi[k] = hi[k].max(it.hi[k]);
                clo[k] = clo[k].min(it.centroid[k]);
                chi[k] = chi[k].max(it.centroid[k]);
            }
        }
        let count = end - start;
        if count <= LEAF_FACES {
            nodes[node] = [lo[0], lo[1], lo[2], bits(start as u32), hi[0], hi[1], hi[2], bits(count as u32)];
            continue;
        }
        let ext: [f32; 3] = std::array::from_fn(|k| chi[k] - clo[k]);
        let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] { 0 } else if ext[1] >= ext[2] { 1 } else { 2 };
        let mid = count / 2;
        range.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]).then(a.slot.cmp(&b.slot)));
        let left = nodes.len();
        nodes.push([0.0; 8]);
        nodes.push([0.0; 8]);
        nodes[node] = [lo[0], lo[1], lo[2], bits(left as u32), hi[0], hi[1], hi[2], bits(0)];
        stack.push((left + 1, start + mid, end, level + 1));
        stack.push((left, start, start + mid, level + 1));
    }
    FaceBvh { nodes, prims: items.iter().map(|it| it.slot).collect(), depth }
}

/// Most BVH nodes one boundary face's hull test visits before it gives up
/// (the face is then treated as one the ray may re-enter after). A flat
/// side of many coplanar faces not aligned with the axes makes every box on
/// it reach past the plane, so a face's test there visits the whole side;
/// the cap keeps the tests linear in the faces. Measured on the oxygen post
/// refined twice (32.9 M tets, 442,816 boundary faces): 1,024 left 10 k of
/// the once-refined mesh's 66.6 k hull faces unmarked, 16,384 marks them
/// all (266,400 at 32.9 M) and the tests take 2.5 s of the 9.9 s set-up.
const HULL_TEST_NODES: usize = 1 << 14;

/// The vertex indices of face `slot` (4 c + f) of the tets, in FACE_VERTS
/// order (counter-clockwise seen from outside a positively oriented cell).
fn face_vertices(tets: &[[u32; 4]], slot: u32) -> [u32; 3] {
    let t = &tets[(slot >> 2) as usize];
    FACE_VERTS[(slot & 3) as usize].map(|l| t[l])
}

/// Face `slot` of the tets: its three corners ([`face_vertices`]) and the
/// cell's fourth vertex, the one opposite it (`point` gives a vertex's
/// position). What `hull_faces` takes as `corners`.
fn face_corners(tets: &[[u32; 4]], slot: u32, point: impl Fn(u32) -> [f32; 3]) -> ([[f32; 3]; 3], [f32; 3]) {
    let opposite = tets[(slot >> 2) as usize][(slot & 3) as usize];
    (face_vertices(tets, slot).map(&point), point(opposite))
}

/// Per boundary face of `bvh` (in `faces`' order): whether it lies on the
/// mesh's convex hull, i.e. no boundary vertex is more than `tol` beyond its
/// plane on the side away from its cell. A ray that leaves the mesh through
/// such a face is outside that plane and moving away from it, so it meets
/// no more of the mesh (every cell lies in the hull of the boundary
/// vertices): the walk ends without the entry search that would find
/// nothing (walk.comp: its neighbour stays `NONE`). A face whose cell is flat or that has no
/// area, or whose test visits more than [`HULL_TEST_NODES`] nodes, is
/// `false`: the search runs, as for every face before. `corners(slot)`
/// gives a face's three vertices and its cell's fourth; `pad` is what the
/// BVH's boxes were padded by.
pub fn hull_faces(faces: &[u32], corners: impl Fn(u32) -> ([[f32; 3]; 3], [f32; 3]) + Sync, bvh: &FaceBvh, pad: f32, tol: f64) -> Vec<bool> {
    use glam::DVec3;
    use rayon::prelude::*;
    let f64s = |p: [f32; 3]| DVec3::from(p.map(f64::from));
    faces
        .par_iter()
        .map(|&slot| {
            let (tri, opposite) = corners(slot);
            let [a, b, c] = tri.map(f64s);
            let n = (b - a).cross(c - a);
            let len = n.length();
            if !(len > 0.0 && len.is_finite()) {
                return false;
            }
            let mut n = n / len;
            // Outward: away from the cell's fourth vertex; a flat cell says
            // nothing about which side is out.
            let side = n.dot(f64s(opposite) - a);
            if !(side.abs() > tol) {
                return false;
            }
            if side > 0.0 {
                n = -n;
            }
            let limit = n.dot(a).max(n.dot(b)).max(n.dot(c)) + tol;
            // Depth first, pruning a node whose box (its padding taken off)
            // lies within the limit along n.
            let slack = f64::from(pad) * n.abs().element_sum();
            let mut stack = vec![0usize];
            let mut visited = 0;
            while let Some(i) = stack.pop() {
                visited += 1;
                if visited > HULL_TEST_NODES {
                    return false;
                }
                let node = &bvh.nodes[i];
                let reach: f64 = (0..3).map(|k| (n[k] * f64::from(node[k])).max(n[k] * f64::from(node[4 + k]))).sum::<f64>() - slack;
                if reach <= limit {
                    continue;
                }
                let first = node[3].to_bits() as usize;
                let count = node[7].to_bits() as usize;
                if count == 0 {
                    stack.push(first);
                    stack.push(first + 1);
                    continue;
                }
                for &other in &bvh.prims[first..first + count] {
                    if corners(other).0.iter().any(|&p| n.dot(f64s(p)) > limit) {
                        return false;
                    }
                }
            }
            true
        })
        .collect()
}

fn create(inputs: MethodInputs) -> Result<Box<dyn RenderMethod>> {
    let SceneData::TetMesh { mesh } = inputs.data else {
        bail!("tet-raycast renders tetrahedral meshes only");
    };
    let settings = Settings::from_options(inputs.options)?;
    TetRaycast::new(inputs.ctx, mesh, inputs.tf, settings, inputs.width, inputs.height, inputs.counter)
        .map(|m| Box::new(m) as Box<dyn RenderMethod>)
}

pub struct TetRaycast {
    tables: IntegrationTables,
    scale: MeshScale,
    settings: Settings,
    mesh_set: DescriptorSet,
    _texel_buffers: Vec<TexelBuffer>,
    counters: Buffer,
    pipeline: Arc<Pipeline>,
    key: PipelineKey,
    target_set: TargetImageSet,
    /// The frame's push constants.
    frame: WalkFrame,
    pixels: u64,
    cells: usize,
    boundary_faces: usize,
    /// Boundary faces on the convex hull ([`hull_faces`]).
    hull_faces: usize,
    /// The boundary faces' vertices (world coordinates), projected per frame
    /// for the pixels that may meet the mesh ([`pixel_rect`]).
    boundary_points: Vec<[f64; 3]>,
    /// The same points as the shader holds them (f32, relative to the render
    /// origin): which way a face faces is decided from these.
    boundary_points_shader: Vec<[f32; 3]>,
    /// The last frame's rectangle ([`pixel_rect`]) and its pixel count: the
    /// dispatch covers only it.
    rect: [u32; 4],
    rect_pixels: u64,
    /// The boundary faces per screen tile ([`tiles`]), when the frame's
    /// rays search them (`pipeline_lists`) instead of the BVH.
    tile_faces: tiles::Faces,
    lists: TileLists,
    lists_active: bool,
    pipeline_lists: Arc<Pipeline>,
    lists_set: DescriptorSet,
    tile_first: TexelBuffer,
    tile_entries: TexelBuffer,
    bvh_nodes: usize,
    bvh_depth: usize,
    /// Texel buffers per array (`algo::chunks`): points, then each per-cell array.
    device_chunks: serde_json::Value,
    step_budget: u64,
    /// Adaptive refinement (`adaptive=TOL`): its state and the walk's
    /// pipelines casting its lattice points (plain, tile lists).
    adaptive: Option<AdaptiveWalk>,
    /// The mesh the run holds for this method (`details.host_memory`;
    /// everything else per cell lives on the device).
    scene_memory: HostMemory,
    ctx: Arc<Context>,
}

impl TetRaycast {
    #[allow(clippy::too_many_arguments)]
    fn new(
        ctx: &Arc<Context>,
        mesh: &TetMesh,
        tf: &crate::scene::TransferFunction,
        settings: Settings,
        width: u32,
        height: u32,
        counter: &mut UploadCounter,
    ) -> Result<Self> {
        let n = mesh.tets.len();
        check_mesh_fits(ctx, mesh)?;
        let tables = integration_tables(ctx, mesh, tf, &settings, counter)?;
        let mut topo = Topology::build(mesh);
        let shader_mesh = ShaderMesh::of(mesh, &topo);
        let boundary = Boundary::build(mesh, &shader_mesh, &mut topo)?;
        let mesh_set = MeshSet::upload(ctx, mesh, &shader_mesh, &topo, &boundary.bvh, counter)?;
        let target_set = TargetImageSet::new("tet-raycast target", Stages::COMPUTE);
        let facts = WalkFacts { cell_constant: !mesh.stats.vertex_origin.is_empty(), chunks: mesh_set.chunk_defines.clone() };
        let lists = TileListSet::new(ctx)?;
        let sets = WalkSets { tables: tables.set.desc.clone(), mesh: mesh_set.desc.clone(), target: target_set.desc.clone(), lists: lists.desc.clone() };
        let key = settings.walk_key(&facts, &sets, false, None);
        let pipeline = crate::algo::pipelines::get(ctx, &key)?;
        let pipeline_lists = crate::algo::pipelines::get(ctx, &settings.walk_key(&facts, &sets, true, None))?;
        let tile_faces = tile_faces(mesh, &topo, &boundary)?;
        let adaptive = AdaptiveWalk::new(ctx, &settings, &facts, &sets, [width, height], &tile_faces)?;
        let mut scene_memory = HostMemory::default();
        scene_memory.scene_mesh(mesh);
        Ok(TetRaycast {
            adaptive,
            scene_memory,
            tables,
            scale: MeshScale::of(mesh),
            settings,
            mesh_set: mesh_set.set,
            _texel_buffers: mesh_set.buffers,
            counters: mesh_set.counters,
            pipeline,
            key,
            target_set,
            frame: bytemuck::Zeroable::zeroed(),
            pixels: u64::from(width) * u64::from(height),
            cells: n,
            boundary_faces: topo.boundary.len(),
            hull_faces: boundary.hull_faces,
            boundary_points: boundary.points,
            boundary_points_shader: boundary.points_shader,
            rect: crate::algo::screen::NO_PIXELS,
            rect_pixels: 0,
            tile_faces,
            lists: TileLists::default(),
            lists_active: false,
            pipeline_lists,
            lists_set: lists.set,
            tile_first: lists.first,
            tile_entries: lists.entries,
            bvh_nodes: boundary.bvh.nodes.len(),
            bvh_depth: boundary.bvh.depth,
            device_chunks: mesh_set.chunks,
            step_budget: n as u64 + STEP_MARGIN,
            ctx: ctx.clone(),
        })
    }

    /// The frame's push constants ([`WalkFrame`]) for its pixel rectangle
    /// `rect`.
    fn frame_constants(&self, view: &View, rect: [u32; 4]) -> WalkFrame {
        let c: &Camera = &view.camera;
        let o = self.scale.origin;
        let eye: [f64; 3] = std::array::from_fn(|k| c.eye[k] - o[k]);
        let (right, up) = c.image_axes(view.width, view.height);
        let f32s = |v: glam::DVec3| v.as_vec3();
        WalkFrame {
            eye: glam::DVec3::from(eye).as_vec3(),
            perspective: if c.is_perspective() { 1.0 } else { 0.0 },
            forward: f32s(c.forward()),
            near: c.near as f32,
            right: f32s(right),
            far: c.far as f32,
            up: f32s(up),
            ert: self.settings.ert as f32,
            // The table range and length scale exactly as the
            // cell-projection methods map them.
            table: self.tables.map(self.scale.scalar_origin, self.scale.scalar_scale),
            entry_tol: (1e-5 * self.scale.diagonal) as f32,
            step_budget: u32::try_from(self.step_budget).unwrap_or(u32::MAX),
            stall_limit: STALL_LIMIT,
            rect,
            // The rectangle's rows of workgroups, interleaved over the
            // device's runs (algo::screen::interleaved_rows).
            rows: rect_groups(rect)[1],
            runs: self.ctx.info.compute_runs(),
            cast_step: 0,
        }
    }

    /// The last frame's counters (`Counters` in walk.comp).
    fn counters(&self) -> [u64; COUNTER_WORDS] {
        self.counters.read_counters()
    }
}

/// Refuses a mesh whose face slots or vertex indices would reach the solid
/// flag's bit, or whose arrays exceed the device's memory.
fn check_mesh_fits(ctx: &Context, mesh: &TetMesh) -> Result<()> {
    let n = mesh.tets.len();
    // Face slots 4 c + f and vertex indices leave the top bit free for
    // the solid flag (SOLID_BIT in walk.comp).
    if (n as u64) * 4 > u64::from(!SOLID_BIT) {
        bail!("mesh '{}': {n} cells are too many for 31-bit face slots", mesh.name);
    }
    if mesh.points.len() as u64 > u64::from(!SOLID_BIT) {
        bail!("mesh '{}': {} points are too many for 31-bit vertex indices", mesh.name, mesh.points.len());
    }
    // The per-point and per-cell arrays are split at the device's
    // limits (`algo::chunks`); their total is checked against its memory.
    let info = &ctx.info;
    let (memory, what) = crate::algo::chunks::device_memory_bound(info);
    crate::mesh::check_fits(n, 16 + 16 + 4 + 4 * 4 + 32, memory)
        .with_context(|| format!("mesh '{}' on {}: device memory ({what})", mesh.name, info.name))?;
    Ok(())
}

/// The integration tables, for the compute stage, at the mesh's length scale.
fn integration_tables(
    ctx: &Arc<Context>,
    mesh: &TetMesh,
    tf: &crate::scene::TransferFunction,
    settings: &Settings,
    counter: &mut UploadCounter,
) -> Result<IntegrationTables> {
    let length_scale = mesh.bounds().diagonal() / (mesh.tets.len().max(1) as f64).cbrt();
    IntegrationTables::for_stages(ctx, tf, mesh.scalar_range(), settings.integrator, settings.table_size, length_scale, Stages::COMPUTE, counter)
        .context("building the integration tables")
}

/// The top bit of cell `c`'s fourth vertex: [`SOLID_BIT`] when it is solid.
fn solid_bit(topo: &Topology, c: usize) -> u32 {
    if topo.solid[c] {
        SOLID_BIT
    } else {
        0
    }
}

/// The mesh's points and cells as the walk reads them.
struct ShaderMesh {
    /// Relative to the render origin, the scalar mapped, in f64 before the
    /// f32 conversion (as every tetrahedral method sends them).
    points: Vec<[f32; 4]>,
    /// The vertex indices, the fourth with the cell's solid flag.
    cells: Vec<[u32; 4]>,
}

impl ShaderMesh {
    fn of(mesh: &TetMesh, topo: &Topology) -> ShaderMesh {
        let origin = render_origin(mesh);
        let (so, ss) = scalar_map(mesh);
        let points = mesh
            .points
            .iter()
            .zip(&mesh.scalars)
            .map(|(p, s)| [(p[0] - origin[0]) as f32, (p[1] - origin[1]) as f32, (p[2] - origin[2]) as f32, ((s - so) / ss) as f32])
            .collect();
        let cells = mesh.tets.iter().enumerate().map(|(c, t)| [t[0], t[1], t[2], t[3] | solid_bit(topo, c)]).collect();
        ShaderMesh { points, cells }
    }

    /// Point `i`'s position as the shader holds it.
    fn xyz(&self, i: u32) -> [f32; 3] {
        let p = self.points[i as usize];
        [p[0], p[1], p[2]]
    }
}

/// The boundary as the entry search and the per-frame projection see it.
struct Boundary {
    /// The boundary faces' vertices, ascending.
    vertices: Vec<u32>,
    /// Their positions: world coordinates, and as the shader holds them.
    points: Vec<[f64; 3]>,
    points_shader: Vec<[f32; 3]>,
    bvh: FaceBvh,
    /// Boundary faces on the convex hull ([`hull_faces`]).
    hull_faces: usize,
}

impl Boundary {
    /// The boundary of `topo`'s mesh, its BVH checked against the shader's
    /// bounds; marks in `topo` the boundary faces off the convex hull as
    /// ones the ray may re-enter after ([`REENTER`]).
    fn build(mesh: &TetMesh, shader: &ShaderMesh, topo: &mut Topology) -> Result<Boundary> {
        // A boundary face's corners and its cell's fourth vertex.
        let corners = |slot: u32| face_corners(&mesh.tets, slot, |i| shader.xyz(i));
        let faces: Vec<(u32, [[f32; 3]; 3])> = topo.boundary.iter().map(|&slot| (slot, corners(slot).0)).collect();
        let mut vertices: Vec<u32> = topo.boundary.iter().flat_map(|&slot| face_vertices(&mesh.tets, slot)).collect();
        vertices.sort_unstable();
        vertices.dedup();
        let points = vertices.iter().map(|&i| mesh.points[i as usize]).collect();
        let points_shader = vertices.iter().map(|&i| shader.xyz(i)).collect();
        let diag = mesh.bounds().diagonal();
        let pad = (1e-5 * diag) as f32;
        let bvh = build_face_bvh(&faces, pad);
        if bvh.depth > MAX_BVH_DEPTH {
            bail!("mesh '{}': boundary-face BVH {} levels deep, more than the shader's {MAX_BVH_DEPTH}", mesh.name, bvh.depth);
        }
        // The traversal stack holds a node's link and count in one word.
        if bvh.nodes.len().max(bvh.prims.len()) as u64 >= 1u64 << (32 - LINK_SHIFT) {
            bail!("mesh '{}': boundary-face BVH of {} nodes over {} faces is too large for the shader's node links", mesh.name, bvh.nodes.len(), bvh.prims.len());
        }
        // A boundary face on the convex hull keeps NONE (the walk ends there);
        // the others become REENTER (the ray may meet the mesh again).
        let on_hull = hull_faces(&topo.boundary, corners, &bvh, pad, 1e-6 * diag);
        let hull_count = on_hull.iter().filter(|&&h| h).count();
        for (&slot, hull) in topo.boundary.iter().zip(on_hull) {
            if !hull {
                topo.neighbor[slot as usize] = REENTER;
            }
        }
        Ok(Boundary { vertices, points, points_shader, bvh, hull_faces: hull_count })
    }
}

/// The mesh on the device: its arrays in texel buffers, the counters, the
/// descriptor set holding them, and how the arrays were split.
struct MeshSet {
    set: DescriptorSet,
    desc: DescriptorSetDesc,
    /// Chunk 0 of each array, the BVH's two, then the other chunks.
    buffers: Vec<TexelBuffer>,
    counters: Buffer,
    /// `details.device_chunks`.
    chunks: serde_json::Value,
    /// The chunking's shader defines (`POINT_*`, `CELL_*`).
    chunk_defines: Vec<(String, String)>,
}

impl MeshSet {
    // Everything the shader reads per ray (points, cells with their solid
    // flags, neighbours, the BVH and its face list) is in storage texel
    // buffers: one inlined imageLoad per lookup, where a storage-buffer load
    // with a per-ray index is, on llvmpipe, a loop over the SIMD lanes per
    // component, and a texelFetch a call (integrate.rs). The BVH nodes are
    // uint texels (their float boxes pass as bits).
    fn upload(ctx: &Arc<Context>, mesh: &TetMesh, shader: &ShaderMesh, topo: &Topology, bvh: &FaceBvh, counter: &mut UploadCounter) -> Result<MeshSet> {
        let limits = ChunkLimits::of(ctx)?;
        // Each array in texel buffers within the device's limits; the two
        // per-cell arrays share one chunk length (the shader's CELL_PER_CHUNK),
        // that of the 16-byte texels.
        let per_point = limits.texel_chunk(16, 1);
        let per_cell = limits.texel_chunk(16, 1);
        let neighbours: &[[u32; 4]] = bytemuck::cast_slice(&topo.neighbor);
        let chunked = [
            TexelChunks::upload_slice(ctx, "tet-raycast points", &shader.points, Format::Rgba32Float, per_point, counter)?,
            TexelChunks::upload_slice(ctx, "tet-raycast cells", &shader.cells, Format::Rgba32Uint, per_cell, counter)?,
            TexelChunks::upload_slice(ctx, "tet-raycast neighbours", neighbours, Format::Rgba32Uint, per_cell, counter)?,
        ];
        let chunks = json!({
            "point_buffers": chunked[0].buffers.len(),
            "points_per_buffer": chunked[0].per_chunk,
            "buffers_per_cell_array": chunked[1].buffers.len(),
            "cells_per_buffer": chunked[1].per_chunk,
        });
        let chunk_defines = chunked[0].defines("POINT").into_iter().chain(chunked[1].defines("CELL")).collect();
        // Chunk 0 of each array at bindings 0-2, the others from binding 6
        // on (walk.comp).
        let (firsts, rests): (Vec<TexelBuffer>, Vec<Vec<TexelBuffer>>) = chunked
            .into_iter()
            .map(|c| {
                let mut buffers = c.buffers;
                let first = buffers.remove(0);
                (first, buffers)
            })
            .unzip();
        let extra: Vec<TexelBuffer> = rests.into_iter().flatten().collect();
        let bvh_buffers = upload_bvh(ctx, mesh, topo, bvh, &limits, counter)?;
        let counters = Buffer::new(ctx, BufferDesc::counters("tet-raycast counters", COUNTER_WORDS))?;
        let compute = Stages::COMPUTE;
        let mut desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageTexelBuffer, compute); 5]).with(DescriptorKind::StorageBuffer, compute);
        for _ in &extra {
            desc = desc.with(DescriptorKind::StorageTexelBuffer, compute);
        }
        let resources: Vec<DescriptorResource> = firsts
            .iter()
            .chain(&bvh_buffers)
            .map(DescriptorResource::StorageTexelBuffer)
            .chain(std::iter::once(DescriptorResource::StorageBuffer(&counters)))
            .chain(extra.iter().map(DescriptorResource::StorageTexelBuffer))
            .collect();
        let set = DescriptorSet::new(ctx, "tet-raycast mesh", &desc, &resources)?;
        let buffers = firsts.into_iter().chain(bvh_buffers).chain(extra).collect();
        Ok(MeshSet { set, desc, buffers, counters, chunks, chunk_defines })
    }
}

/// The BVH and its face list (slot with the solid flag, three vertex
/// indices) in one texel buffer each: the shader declares no chunks for
/// them (a BVH that large would need more boundary faces than any mesh
/// that fits the device).
fn upload_bvh(ctx: &Arc<Context>, mesh: &TetMesh, topo: &Topology, bvh: &FaceBvh, limits: &ChunkLimits, counter: &mut UploadCounter) -> Result<Vec<TexelBuffer>> {
    let node_texels: &[[u32; 4]] = bytemuck::cast_slice(&bvh.nodes);
    let face_texels: Vec<[u32; 4]> = bvh
        .prims
        .iter()
        .map(|&slot| {
            let [a, b, d] = face_vertices(&mesh.tets, slot);
            [slot | solid_bit(topo, (slot >> 2) as usize), a, b, d]
        })
        .collect();
    let uploads = [
        TexelChunks::upload_slice(ctx, "tet-raycast boundary BVH", node_texels, Format::Rgba32Uint, limits.texel_chunk(16, 1), counter)?,
        TexelChunks::upload_slice(ctx, "tet-raycast boundary faces", &face_texels, Format::Rgba32Uint, limits.texel_chunk(16, 1), counter)?,
    ];
    let mut buffers = Vec::with_capacity(2);
    for chunks in uploads {
        if chunks.buffers.len() > 1 {
            bail!(
                "mesh '{}': the boundary-face BVH ({} nodes, {} faces) is larger than one texel buffer of the device ({} elements)",
                mesh.name,
                bvh.nodes.len(),
                bvh.prims.len(),
                chunks.per_chunk
            );
        }
        buffers.extend(chunks.buffers);
    }
    Ok(buffers)
}

/// The per-frame tile lists' buffers (grown as a frame needs) and their
/// set (set 3 of the walk that searches them).
struct TileListSet {
    first: TexelBuffer,
    entries: TexelBuffer,
    desc: DescriptorSetDesc,
    set: DescriptorSet,
}

impl TileListSet {
    fn new(ctx: &Arc<Context>) -> Result<TileListSet> {
        let desc = DescriptorSetDesc::new(&[(DescriptorKind::StorageTexelBuffer, Stages::COMPUTE); 2]);
        let first = frame_texels(ctx, "tet-raycast tile starts", 1, 4, Format::R32Uint)?;
        let entries = frame_texels(ctx, "tet-raycast tile faces", 1, 4, Format::R32Uint)?;
        let resources = [DescriptorResource::StorageTexelBuffer(&first), DescriptorResource::StorageTexelBuffer(&entries)];
        let set = DescriptorSet::new(ctx, "tet-raycast tile lists", &desc, &resources)?;
        Ok(TileListSet { first, entries, desc, set })
    }
}

/// Per face of the shader's face list (the BVH's order): its corners among
/// the boundary points and its cell's solidity, what the tile lists and
/// the silhouettes are made from.
fn tile_faces(mesh: &TetMesh, topo: &Topology, boundary: &Boundary) -> Result<tiles::Faces> {
    let index = |v: u32| boundary.vertices.binary_search(&v).map(|i| i as u32).map_err(|_| anyhow::anyhow!("boundary vertex {v} not indexed"));
    let prims = &boundary.bvh.prims;
    let mut faces = tiles::Faces { corners: Vec::with_capacity(prims.len()), solid: Vec::with_capacity(prims.len()) };
    for &slot in prims {
        let [a, b, d] = face_vertices(&mesh.tets, slot);
        faces.corners.push([index(a)?, index(b)?, index(d)?]);
        faces.solid.push(topo.solid[(slot >> 2) as usize]);
    }
    Ok(faces)
}

/// `adaptive=TOL`: the shared refinement state ([`Adaptive`]), the walk
/// compiled with ADAPTIVE (its set after the others), the boundary's edges
/// for the silhouettes, and whether this frame refines (the boundary
/// projected: every point in front of the eye; else the frame casts every
/// pixel).
struct AdaptiveWalk {
    state: Adaptive,
    pipeline: Arc<Pipeline>,
    pipeline_lists: Arc<Pipeline>,
    edges: BoundaryEdges,
    active: bool,
}

impl AdaptiveWalk {
    /// With `adaptive=TOL`: the refinement's state and the walk's two
    /// variants compiled with ADAPTIVE; `None` without.
    fn new(ctx: &Arc<Context>, settings: &Settings, facts: &WalkFacts, sets: &WalkSets, [width, height]: [u32; 2], faces: &tiles::Faces) -> Result<Option<AdaptiveWalk>> {
        if settings.adaptive <= 0.0 {
            return Ok(None);
        }
        let state = Adaptive::new(ctx, "tet-raycast", settings.adaptive, width, height, true)?;
        let pipeline = crate::algo::pipelines::get(ctx, &settings.walk_key(facts, sets, false, Some(&state.desc)))?;
        let pipeline_lists = crate::algo::pipelines::get(ctx, &settings.walk_key(facts, sets, true, Some(&state.desc)))?;
        Ok(Some(AdaptiveWalk { state, pipeline, pipeline_lists, edges: BoundaryEdges::new(faces), active: false }))
    }
}

/// The counters by name.
struct Counts {
    cells: u64,
    max_cells: u64,
    rays_hit: u64,
    terminated: u64,
    reentering: u64,
    bound_hits: u64,
    stalled: u64,
    fallback_exits: u64,
    reversed: u64,
    walks: u64,
    searches: u64,
    nodes_visited: u64,
    faces_tested: u64,
}

impl From<[u64; COUNTER_WORDS]> for Counts {
    fn from(c: [u64; COUNTER_WORDS]) -> Self {
        Counts {
            cells: c[0] | (c[1] << 32),
            max_cells: c[2],
            rays_hit: c[3],
            terminated: c[4],
            reentering: c[5],
            bound_hits: c[6],
            stalled: c[7],
            fallback_exits: c[8],
            reversed: c[9],
            walks: c[10],
            searches: c[11],
            nodes_visited: c[12],
            faces_tested: c[13],
        }
    }
}

impl RenderMethod for TetRaycast {
    fn prepare(&mut self, view: &View, phases: &mut Phases) -> Result<()> {
        let start = std::time::Instant::now();
        let c: &Camera = &view.camera;
        let (w, h) = (view.width, view.height);
        let (right, up) = c.image_axes(w, h);
        let camera = tiles::View {
            eye: c.eye,
            forward: c.forward().into(),
            right: right.into(),
            up: up.into(),
            perspective: c.is_perspective(),
            size: [w, h],
        };
        // The boundary points projected once: the rectangle, then the lists.
        let projected = camera.project(&self.boundary_points);
        self.rect = rect_of(&projected, [w, h]).unwrap_or([0, 0, w.saturating_sub(1), h.saturating_sub(1)]);
        let [x0, y0, x1, y1] = self.rect;
        self.rect_pixels = if x0 > x1 || y0 > y1 { 0 } else { u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) };
        self.frame = self.frame_constants(view, self.rect);
        self.lists_active = self.rect_pixels > 0
            && self.settings.search == Search::Auto
            && self.lists.build(
                &self.tile_faces,
                &projected,
                &self.boundary_points_shader,
                std::array::from_fn(|k| f64::from((c.eye[k] - self.scale.origin[k]) as f32)),
                &camera,
                self.rect,
                TILE_PAD,
                u64::from(self.ctx.info.max_texel_buffer_elements),
            );
        if let Some(a) = &mut self.adaptive {
            // Refine only when the boundary projects (every point in front
            // of the eye) and lies within the clip depths: the silhouettes
            // are then where rays start or stop meeting the mesh.
            a.active = false;
            if let (true, Projected::Pixels(px)) = (self.rect_pixels > 0, &projected) {
                let fwd = glam::DVec3::from(camera.forward);
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for p in &self.boundary_points {
                    let d = (glam::DVec3::from(*p) - glam::DVec3::from(c.eye)).dot(fwd);
                    lo = lo.min(d);
                    hi = hi.max(d);
                }
                if lo >= c.near && hi <= c.far {
                    a.state.frame(self.rect, [w, h])?;
                    let eye: [f64; 3] = std::array::from_fn(|k| f64::from((c.eye[k] - self.scale.origin[k]) as f32));
                    let segments = a.edges.silhouettes(&self.tile_faces, px, &self.boundary_points_shader, eye, &camera);
                    a.state.set_silhouettes(Silhouettes::mark(self.rect, segments, SILHOUETTE_PAD));
                    a.active = true;
                }
            }
        }
        phases.ended("bin", start.elapsed().as_secs_f64() * 1e3);
        Ok(())
    }

    fn upload(&mut self, counter: &mut UploadCounter) -> Result<()> {
        if let Some(a) = self.adaptive.as_mut().filter(|a| a.active) {
            a.state.upload(counter)?;
        }
        if !self.lists_active {
            return Ok(());
        }
        let ctx = self.ctx.clone();
        let grown_first = ensure_frame_texels(&ctx, &mut self.tile_first, self.lists.first.len(), 4, "tet-raycast tile starts")?;
        let grown_entries = ensure_frame_texels(&ctx, &mut self.tile_entries, self.lists.faces.len(), 4, "tet-raycast tile faces")?;
        if grown_first || grown_entries {
            self.lists_set.update(&[DescriptorResource::StorageTexelBuffer(&self.tile_first), DescriptorResource::StorageTexelBuffer(&self.tile_entries)])?;
        }
        self.tile_first.buffer.write(0, bytemuck::cast_slice(&self.lists.first), counter, UploadClass::FrameCells)?;
        self.tile_entries.buffer.write(0, bytemuck::cast_slice(&self.lists.faces), counter, UploadClass::FrameCells)?;
        Ok(())
    }

    fn record(&mut self, rec: &CommandRecorder, target: &Image, _view: &View, counter: &mut UploadCounter) -> Result<()> {
        let set = self.target_set.for_target(&self.ctx, target)?;
        rec.fill_buffer(&self.counters, 0);
        rec.transfer_to_storage(Stages::COMPUTE);
        // Only the rectangle's pixels run the shader: on llvmpipe an
        // invocation that returns at once still runs the whole shader
        // masked (its branches and loops are not skipped), ~50 ns a pixel
        // at 512x512 (docs/compute-speed.md). The rest is cleared.
        let [gx, gy, _] = rect_groups(self.rect);
        let groups = [gx, screen::interleaved_rows(gy, self.ctx.info.compute_runs()), 1];
        rec.storage_target(target, self.rect);
        if let Some(a) = self.adaptive.as_mut().filter(|a| a.active) {
            // Adaptive refinement: the lattice of 8, then the listed blocks
            // (algo::adaptive), each cast pass this walk with its step.
            let lists_active = self.lists_active;
            let (tables, mesh, lists) = (&self.tables.set, &self.mesh_set, &self.lists_set);
            let (pipeline, pipeline_lists) = (&a.pipeline, &a.pipeline_lists);
            let frame = self.frame;
            a.state.record(rec, target, counter, |rec, state, step, rows, counter| {
                let pipeline = if lists_active { pipeline_lists } else { pipeline };
                if lists_active {
                    rec.bind_compute(pipeline, &[tables, mesh, set, lists, state])?;
                } else {
                    rec.bind_compute(pipeline, &[tables, mesh, set, state])?;
                }
                // The step and its lattice's rows of workgroups.
                let push = WalkFrame { rows, cast_step: step, ..frame };
                rec.push_constants(pipeline, bytemuck::bytes_of(&push), counter);
                Ok(())
            })?;
            return Ok(());
        }
        if let Some(a) = self.adaptive.as_mut() {
            a.state.skipped();
        }
        if self.lists_active {
            rec.bind_compute(&self.pipeline_lists, &[&self.tables.set, &self.mesh_set, set, &self.lists_set])?;
            rec.push_constants(&self.pipeline_lists, bytemuck::bytes_of(&self.frame), counter);
        } else {
            rec.bind_compute(&self.pipeline, &[&self.tables.set, &self.mesh_set, set])?;
            rec.push_constants(&self.pipeline, bytemuck::bytes_of(&self.frame), counter);
        }
        rec.dispatch(groups)?;
        rec.compute_to_host();
        Ok(())
    }

    fn work(&self) -> Work {
        let c = Counts::from(self.counters());
        let w = Work::default()
            .with("cells", self.cells as u64)
            .with("pixels", self.pixels)
            .with("rays_hit", c.rays_hit)
            .with("cells_visited", c.cells)
            .with("max_cells_per_ray", c.max_cells)
            .with("rays_terminated_early", c.terminated)
            .with("rays_reentering", c.reentering)
            .with("walk_bound_hits", c.bound_hits)
            .with("stalled_walks", c.stalled)
            .with("fallback_exits", c.fallback_exits)
            .with("walks", c.walks)
            .with("pixels_in_rect", self.rect_pixels)
            .with("tile_list_entries", if self.lists_active { self.lists.faces.len() as u64 } else { 0 })
            .with("entry_searches", c.searches)
            .with("bvh_nodes_visited", c.nodes_visited)
            .with("boundary_faces_tested", c.faces_tested);
        match self.adaptive.as_ref().filter(|a| a.active) {
            Some(a) => a.state.work(w),
            None => w,
        }
    }

    fn details(&self) -> serde_json::Value {
        let c = Counts::from(self.counters());
        let mean = |total: u64, of: u64| if of > 0 { total as f64 / of as f64 } else { 0.0 };
        let mut d = json!({
            "host_memory": self.scene_memory.to_json(self.cells),
            "family": "tet-raycast",
            "workgroup": WORKGROUP,
            "pipeline": { "key": self.key.id(), "name": self.key.name() },
            "table_size": self.tables.table_size,
            "ert": self.settings.ert,
            "boundary_faces": self.boundary_faces,
            "hull_faces": self.hull_faces,
            "entry_search": if self.lists_active { "tile lists" } else { "bvh" },
            "tile": TILE,
            "tiles": if self.lists_active { self.lists.tiles } else { [0, 0] },
            "device_chunks": self.device_chunks,
            "bvh_nodes": self.bvh_nodes,
            "bvh_depth": self.bvh_depth,
            "bvh_leaf_faces": LEAF_FACES,
            "step_budget_per_ray": self.step_budget,
            "stall_limit": STALL_LIMIT,
            "cells_per_ray_mean": mean(c.cells, c.rays_hit),
            "cells_per_pixel_mean": mean(c.cells, self.pixels),
            "cells_per_ray_max": c.max_cells,
            "rays_hit": c.rays_hit,
            "rays_terminated_early": c.terminated,
            "rays_reentering": c.reentering,
            "walk_bound_hits": c.bound_hits,
            "stalled_walks": c.stalled,
            "fallback_exits": c.fallback_exits,
            "reversed_walks": c.reversed,
            "walks": c.walks,
            "entry_searches": c.searches,
            "bvh_nodes_visited": c.nodes_visited,
            "boundary_faces_tested": c.faces_tested,
            "bvh_nodes_per_search_mean": mean(c.nodes_visited, c.searches),
        });
        if let Some(a) = &self.adaptive {
            d["adaptive"] = if a.active {
                a.state.details(self.rect_pixels)
            } else {
                json!({ "tolerance": a.state.tol, "refined": false,
                    "why": "a boundary point behind the eye or outside the clip depths: every pixel cast" })
            };
        }
        d
    }

    fn table_build_ms(&self) -> f64 {
        self.tables.build_ms
    }

    /// Adaptive refinement's time per pass (`algo::adaptive::PASS_PHASES`),
    /// for a frame that refined.
    fn after_frame(&mut self, phases: &mut Phases) -> Result<()> {
        if let Some(a) = &self.adaptive {
            for (name, ms) in a.state.device_phases()? {
                phases.add(name, ms);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `hull_faces` over a mesh's boundary, as `TetRaycast::new` calls it.
    fn hull_of(mesh: &TetMesh) -> Vec<(u32, bool)> {
        let topo = Topology::build(mesh);
        let corners = |slot: u32| face_corners(&mesh.tets, slot, |i| mesh.points[i as usize].map(|v| v as f32));
        let faces: Vec<(u32, [[f32; 3]; 3])> = topo.boundary.iter().map(|&s| (s, corners(s).0)).collect();
        let pad = 1e-5;
        let bvh = build_face_bvh(&faces, pad);
        topo.boundary.iter().copied().zip(hull_faces(&topo.boundary, corners, &bvh, pad, 1e-6)).collect()
    }

    #[test]
    fn hull_faces_are_the_faces_on_the_convex_hull() {
        // An L of three unit cubes (a 2x2x1 block without the cube at
        // x, y > 1), split into tets: the faces on the block's box planes
        // are on the hull, the two inner sides of the L (x = 1 or y = 1,
        // facing the missing cube) are not.
        let dims = [3usize, 3, 2];
        let points: Vec<[f64; 3]> = (0..18).map(|i| [(i % 3) as f64, ((i / 3) % 3) as f64, (i / 9) as f64]).collect();
        let scalars = vec![0.0; points.len()];
        let mut mesh = crate::mesh::split::hex_grid_to_tets("L", dims, points, scalars).unwrap();
        let centroid = |t: &[u32; 4]| -> [f64; 3] { std::array::from_fn(|a| t.iter().map(|&v| mesh.points[v as usize][a]).sum::<f64>() / 4.0) };
        mesh.tets = mesh.tets.iter().copied().filter(|t| { let c = centroid(t); !(c[0] > 1.0 && c[1] > 1.0) }).collect();
        let hull = hull_of(&mesh);
        assert!(!hull.is_empty());
        let mut inner = 0;
        for (slot, on) in hull {
            let t = mesh.tets[(slot >> 2) as usize];
            let v = FACE_VERTS[(slot & 3) as usize].map(|l| mesh.points[t[l] as usize]);
            let on_box = (0..3).any(|a| v.iter().all(|p| p[a] == 0.0) || v.iter().all(|p| p[a] == if a == 2 { 1.0 } else { 2.0 }));
            inner += usize::from(!on_box);
            assert_eq!(on, on_box, "face {slot}: {v:?}");
        }
        // The L's two inner sides, two triangles each.
        assert_eq!(inner, 4);

        // A flat cell says nothing about which side is out.
        let flat = TetMesh {
            name: "flat".into(),
            points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]],
            scalars: vec![0.0; 4],
            tets: vec![[0, 1, 2, 3]],
            stats: Default::default(),
        };
        assert!(hull_of(&flat).iter().all(|&(_, on)| !on));
    }

    #[test]
    fn bvh_holds_every_face_once_within_its_leaf_boxes() {
        let faces: Vec<(u32, [[f32; 3]; 3])> = (0..37u32)
            .map(|i| {
                let x = (i % 7) as f32;
                let y = (i / 7) as f32;
                (4 * i + 1, [[x, y, 0.0], [x + 1.0, y, 0.0], [x, y + 1.0, 0.5]])
            })
            .collect();
        let bvh = build_face_bvh(&faces, 0.0);
        let mut seen: Vec<u32> = bvh.prims.clone();
        seen.sort_unstable();
        assert_eq!(seen, faces.iter().map(|f| f.0).collect::<Vec<_>>());
        // Every leaf's box holds its faces; every inner node's box its children's.
        let mut leaves = 0;
        for n in &bvh.nodes {
            let (first, count) = (n[3].to_bits() as usize, n[7].to_bits() as usize);
            if count == 0 {
                for c in [first, first + 1] {
                    for k in 0..3 {
                        assert!(bvh.nodes[c][k] >= n[k] && bvh.nodes[c][4 + k] <= n[4 + k]);
                    }
                }
                continue;
            }
            leaves += count;
            assert!(count <= LEAF_FACES);
            for &slot in &bvh.prims[first..first + count] {
                let p = faces.iter().find(|f| f.0 == slot).unwrap().1;
                for v in p {
                    for k in 0..3 {
                        assert!(v[k] >= n[k] && v[k] <= n[4 + k]);
                    }
                }
            }
        }
        assert_eq!(leaves, faces.len());
        assert!(bvh.depth <= 5, "{}", bvh.depth);
        // Deterministic.
        assert_eq!(bvh, build_face_bvh(&faces, 0.0));
        // No faces: one node no ray enters (min above max).
        let empty = build_face_bvh(&[], 0.0);
        assert_eq!(empty.nodes.len(), 1);
        assert!(empty.nodes[0][0] > empty.nodes[0][4]);
    }

    #[test]
    fn pixel_rect_holds_every_ray_through_a_boundary_point() {
        // The ray through a pixel centre as the shader forms it; the pixel
        // nearest to where each point projects must be inside the rect, at
        // two image sizes and in both projections.
        let cam = Camera::orbit(&crate::mesh::Bounds { min: [-1.0, -2.0, -0.5], max: [3.0, 1.0, 0.5] }, 0.7, crate::scene::Projection::Perspective { fovy_deg: 30.0 });
        let pts: Vec<[f64; 3]> = (0..200).map(|i| {
            let f = i as f64;
            [-1.0 + 4.0 * ((f * 0.37) % 1.0), -2.0 + 3.0 * ((f * 0.61) % 1.0), -0.5 + ((f * 0.13) % 1.0)]
        }).collect();
        for ortho in [false, true] {
            let mut c = cam;
            if ortho {
                c.projection = crate::scene::Projection::Orthographic { height: 6.0 };
            }
            for (w, h) in [(64u32, 48u32), (512, 512)] {
                let rel: Vec<[f64; 3]> = pts.iter().map(|p| std::array::from_fn(|k| p[k] - c.eye[k])).collect();
                let (right, up) = c.image_axes(w, h);
                let fwd = c.forward();
                let r = pixel_rect(&rel, fwd.into(), right.into(), up.into(), !ortho, w, h).unwrap();
                assert!(r[0] <= r[2] && r[1] <= r[3] && r[2] < w && r[3] < h, "{r:?}");
                for q in &rel {
                    let q = glam::DVec3::from(*q);
                    let depth = if ortho { 1.0 } else { q.dot(fwd) };
                    let nx = q.dot(right) / (right.length_squared() * depth);
                    let ny = -q.dot(up) / (up.length_squared() * depth);
                    let px = ((nx + 1.0) * 0.5 * w as f64).floor().clamp(0.0, w as f64 - 1.0) as u32;
                    let py = ((ny + 1.0) * 0.5 * h as f64).floor().clamp(0.0, h as f64 - 1.0) as u32;
                    assert!(px >= r[0] && px <= r[2] && py >= r[1] && py <= r[3], "{w}x{h} ortho {ortho}: pixel ({px}, {py}) outside {r:?}");
                }
                // The rect is tight: not the whole image for this view.
                assert!((r[2] - r[0] + 1) * (r[3] - r[1] + 1) < w * h, "{r:?}");
            }
        }
        // Points on both sides of the eye plane in perspective: every pixel
        // searches; all at or behind it: none does.
        let f: [f64; 3] = cam.forward().into();
        let (right, up) = cam.image_axes(64, 64);
        let rel = vec![[0.0, 0.0, 0.0], f];
        assert_eq!(pixel_rect(&rel, f, right.into(), up.into(), true, 64, 64), None);
        let rel = vec![[0.0, 0.0, 0.0], f.map(|v| -v), [-f[0] + 1.0, -f[1], -f[2]]];
        let r = pixel_rect(&rel, f, right.into(), up.into(), true, 64, 64).unwrap();
        assert!(r[0] > r[2], "{r:?}");
        // In orthographic projection depth does not matter.
        assert!(pixel_rect(&rel, f, right.into(), up.into(), false, 64, 64).is_some_and(|r| r[0] <= r[2]));
        // No boundary: no pixel.
        let r = pixel_rect(&[], cam.forward().into(), right.into(), up.into(), true, 64, 64).unwrap();
        assert!(r[0] > r[2]);
    }

    #[test]
    fn accuracy_bound_adds_what_termination_drops() {
        // Through the method's own entry (the registry's parse ends here too).
        let s = METHOD.options_from([]).unwrap();
        assert!((accuracy_bound(&s, true).unwrap() - (1e-3 + 1e-3)).abs() < 1e-12);
        let s = METHOD.options_from([("integrator", "average"), ("ert", "1")]).unwrap();
        assert_eq!(accuracy_bound(&s, false), Some(5e-3));
        assert!(METHOD.options_from([("ert", "0.2")]).is_err());
        assert!(METHOD.options_from([("sort", "mpvo")]).unwrap_err().to_string().contains("no option 'sort'"));
    }
}
