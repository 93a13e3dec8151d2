#version 450
// Tetrahedral ray casting (Weiler, Kraus, Merz, Ertl, Vis 2003) in one
// compute pass: one invocation per pixel. The ray finds its first boundary
// face that it enters (a BVH over the boundary faces, built once), walks
// cell to cell through face adjacency integrating each segment with the
// shared integrator (common/integrate.glsl), and when it leaves the mesh
// looks for the next boundary face it enters (non-convex meshes, seams).
// Crossings are decided as the f64 reference decides them
// (src/reference/raycast.rs): Plücker edge values of the ray against the
// mesh's edges, each computed from its canonical orientation (lower vertex
// index first) with `precise` arithmetic, so the two cells sharing a face and
// the faces sharing an edge see bit-identical numbers, and zero values take
// the sign of a symbolic perturbation of the ray. The exit point of one cell
// is the entry of the next (carried, not recomputed), so depths telescope.
// The whole line is searched for entries (as the reference does): a ray whose
// eye lies inside the mesh starts its walk behind the eye and integrates
// only from the near plane on.
#ifndef WG_X
#define WG_X 8
#define WG_Y 8
#endif
layout(local_size_x = WG_X, local_size_y = WG_Y) in;

#include "tet_raycast/frame.glsl"

#include "common/integrate.glsl"
#include "common/dispatch.glsl"
#ifdef ADAPTIVE
// Adaptive refinement (algo/adaptive.rs): this pass casts the lattice
// points of step cast_step (8: the lattice of 8 over the rectangle; 4, 2, 1:
// the listed blocks' centres and edge mid-points), storing each ray's colour and
// its structural key (the boundary entries it took) for the decide passes.
#include "common/adaptive.glsl"
#endif

// set 1: the mesh, uploaded once. What the walk reads per cell is in
// storage texel buffers, read with imageLoad (one load per lookup, inlined;
// tet_raycast.rs and integrate.rs say why).
// A mesh larger than one texel buffer may hold (algo/chunks.rs) comes in
// POINT_CHUNKS buffers of POINT_PER_CHUNK points and, for each per-cell
// array, CELL_CHUNKS buffers of CELL_PER_CHUNK cells: chunk 0 at the
// array's binding below, the others after the counters (binding 6 on), the
// points' first, then the cells' and the neighbours'.
#ifndef POINT_CHUNKS
#define POINT_CHUNKS 1
#endif
#ifndef CELL_CHUNKS
#define CELL_CHUNKS 1
#endif
#define POINT_CHUNK_BINDING 6
#define TET_CHUNK_BINDING (POINT_CHUNK_BINDING + POINT_CHUNKS - 1)
#define NEIGHBOR_CHUNK_BINDING (TET_CHUNK_BINDING + CELL_CHUNKS - 1)
layout(set = 1, binding = 0, rgba32f) uniform readonly imageBuffer points_tb;      // xyz: position; w: scalar
layout(set = 1, binding = 1, rgba32ui) uniform readonly uimageBuffer tets_tb;       // vertex indices, w | SOLID_BIT if solid
layout(set = 1, binding = 2, rgba32ui) uniform readonly uimageBuffer neighbors_tb;  // cell c: [f] = 4 c' + f', NONE or REENTER on the boundary
// A cell's solid flag (positive volume; flat cells are crossed either way)
// rides in the top bit of its fourth vertex index and of its boundary faces'
// slots (tet_raycast.rs checks both stay below it): no fetch of its own.
const uint SOLID_BIT = 0x80000000u;
#if POINT_CHUNKS > 1
layout(set = 1, binding = POINT_CHUNK_BINDING + 0, rgba32f) uniform readonly imageBuffer points_tb_1;
#endif
#if POINT_CHUNKS > 2
layout(set = 1, binding = POINT_CHUNK_BINDING + 1, rgba32f) uniform readonly imageBuffer points_tb_2;
#endif
#if POINT_CHUNKS > 3
layout(set = 1, binding = POINT_CHUNK_BINDING + 2, rgba32f) uniform readonly imageBuffer points_tb_3;
#endif
#if POINT_CHUNKS > 4
layout(set = 1, binding = POINT_CHUNK_BINDING + 3, rgba32f) uniform readonly imageBuffer points_tb_4;
#endif
#if POINT_CHUNKS > 5
layout(set = 1, binding = POINT_CHUNK_BINDING + 4, rgba32f) uniform readonly imageBuffer points_tb_5;
#endif
#if POINT_CHUNKS > 6
layout(set = 1, binding = POINT_CHUNK_BINDING + 5, rgba32f) uniform readonly imageBuffer points_tb_6;
#endif
#if POINT_CHUNKS > 7
layout(set = 1, binding = POINT_CHUNK_BINDING + 6, rgba32f) uniform readonly imageBuffer points_tb_7;
#endif
#if CELL_CHUNKS > 1
layout(set = 1, binding = TET_CHUNK_BINDING + 0, rgba32ui) uniform readonly uimageBuffer tets_tb_1;
#endif
#if CELL_CHUNKS > 2
layout(set = 1, binding = TET_CHUNK_BINDING + 1, rgba32ui) uniform readonly uimageBuffer tets_tb_2;
#endif
#if CELL_CHUNKS > 3
layout(set = 1, binding = TET_CHUNK_BINDING + 2, rgba32ui) uniform readonly uimageBuffer tets_tb_3;
#endif
#if CELL_CHUNKS > 4
layout(set = 1, binding = TET_CHUNK_BINDING + 3, rgba32ui) uniform readonly uimageBuffer tets_tb_4;
#endif
#if CELL_CHUNKS > 5
layout(set = 1, binding = TET_CHUNK_BINDING + 4, rgba32ui) uniform readonly uimageBuffer tets_tb_5;
#endif
#if CELL_CHUNKS > 6
layout(set = 1, binding = TET_CHUNK_BINDING + 5, rgba32ui) uniform readonly uimageBuffer tets_tb_6;
#endif
#if CELL_CHUNKS > 7
layout(set = 1, binding = TET_CHUNK_BINDING + 6, rgba32ui) uniform readonly uimageBuffer tets_tb_7;
#endif
#if CELL_CHUNKS > 1
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 0, rgba32ui) uniform readonly uimageBuffer neighbors_tb_1;
#endif
#if CELL_CHUNKS > 2
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 1, rgba32ui) uniform readonly uimageBuffer neighbors_tb_2;
#endif
#if CELL_CHUNKS > 3
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 2, rgba32ui) uniform readonly uimageBuffer neighbors_tb_3;
#endif
#if CELL_CHUNKS > 4
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 3, rgba32ui) uniform readonly uimageBuffer neighbors_tb_4;
#endif
#if CELL_CHUNKS > 5
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 4, rgba32ui) uniform readonly uimageBuffer neighbors_tb_5;
#endif
#if CELL_CHUNKS > 6
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 5, rgba32ui) uniform readonly uimageBuffer neighbors_tb_6;
#endif
#if CELL_CHUNKS > 7
layout(set = 1, binding = NEIGHBOR_CHUNK_BINDING + 6, rgba32ui) uniform readonly uimageBuffer neighbors_tb_7;
#endif
vec4 point_at(uint i) {
#if POINT_CHUNKS > 1
    uint k = (i) / uint(POINT_PER_CHUNK);
    int j = int((i) - k * uint(POINT_PER_CHUNK));
    switch (k) {
#if POINT_CHUNKS > 1
    case 1u: return imageLoad(points_tb_1, j);
#endif
#if POINT_CHUNKS > 2
    case 2u: return imageLoad(points_tb_2, j);
#endif
#if POINT_CHUNKS > 3
    case 3u: return imageLoad(points_tb_3, j);
#endif
#if POINT_CHUNKS > 4
    case 4u: return imageLoad(points_tb_4, j);
#endif
#if POINT_CHUNKS > 5
    case 5u: return imageLoad(points_tb_5, j);
#endif
#if POINT_CHUNKS > 6
    case 6u: return imageLoad(points_tb_6, j);
#endif
#if POINT_CHUNKS > 7
    case 7u: return imageLoad(points_tb_7, j);
#endif
    default: return imageLoad(points_tb, j);
    }
#else
    return imageLoad(points_tb, int(i));
#endif
}
uvec4 tet_at(uint c) {
#if CELL_CHUNKS > 1
    uint k = (c) / uint(CELL_PER_CHUNK);
    int j = int((c) - k * uint(CELL_PER_CHUNK));
    switch (k) {
#if CELL_CHUNKS > 1
    case 1u: return imageLoad(tets_tb_1, j);
#endif
#if CELL_CHUNKS > 2
    case 2u: return imageLoad(tets_tb_2, j);
#endif
#if CELL_CHUNKS > 3
    case 3u: return imageLoad(tets_tb_3, j);
#endif
#if CELL_CHUNKS > 4
    case 4u: return imageLoad(tets_tb_4, j);
#endif
#if CELL_CHUNKS > 5
    case 5u: return imageLoad(tets_tb_5, j);
#endif
#if CELL_CHUNKS > 6
    case 6u: return imageLoad(tets_tb_6, j);
#endif
#if CELL_CHUNKS > 7
    case 7u: return imageLoad(tets_tb_7, j);
#endif
    default: return imageLoad(tets_tb, j);
    }
#else
    return imageLoad(tets_tb, int(c));
#endif
}
uvec4 neighbors_of(uint c) {
#if CELL_CHUNKS > 1
    uint k = (c) / uint(CELL_PER_CHUNK);
    int j = int((c) - k * uint(CELL_PER_CHUNK));
    switch (k) {
#if CELL_CHUNKS > 1
    case 1u: return imageLoad(neighbors_tb_1, j);
#endif
#if CELL_CHUNKS > 2
    case 2u: return imageLoad(neighbors_tb_2, j);
#endif
#if CELL_CHUNKS > 3
    case 3u: return imageLoad(neighbors_tb_3, j);
#endif
#if CELL_CHUNKS > 4
    case 4u: return imageLoad(neighbors_tb_4, j);
#endif
#if CELL_CHUNKS > 5
    case 5u: return imageLoad(neighbors_tb_5, j);
#endif
#if CELL_CHUNKS > 6
    case 6u: return imageLoad(neighbors_tb_6, j);
#endif
#if CELL_CHUNKS > 7
    case 7u: return imageLoad(neighbors_tb_7, j);
#endif
    default: return imageLoad(neighbors_tb, j);
    }
#else
    return imageLoad(neighbors_tb, int(c));
#endif
}
uint neighbor_at(uint slot) { return neighbors_of(slot >> 2)[slot & 3u]; }
// The BVH over the boundary faces and its face list, as uint texels (a
// node's box is float bits, its links uint: uintBitsToFloat keeps both
// exact). Texel loads, not storage-buffer loads: the traversal's node
// index differs per lane, and llvmpipe loads a storage buffer at a per-lane
// index one lane at a time, where a texel load is one gather.
struct Node {
    vec3 lo;     // box min
    vec3 hi;     // box max
    uint first;  // inner: left child index (right = left + 1); leaf: first primitive
    uint count;  // 0 for an inner node, else the primitive count
};
layout(set = 1, binding = 3, rgba32ui) uniform readonly uimageBuffer bvh_tb;    // node n: texels 2n (min, first), 2n + 1 (max, count)
// Boundary faces in leaf order: (slot 4 c + f | SOLID_BIT if cell c is
// solid, the face's three vertex indices in FACE_VERTS order), so a face
// test fetches this texel and the three points, not the cell too.
layout(set = 1, binding = 4, rgba32ui) uniform readonly uimageBuffer prims_tb;
Node node_at(uint n) {
    uvec4 a = imageLoad(bvh_tb, int(2u * n));
    uvec4 b = imageLoad(bvh_tb, int(2u * n + 1u));
    return Node(uintBitsToFloat(a.xyz), uintBitsToFloat(b.xyz), a.w, b.w);
}
// A node's link and primitive count in one word (first << LINK_SHIFT |
// count; tet_raycast.rs checks that node and face indices fit).
const uint LINK_SHIFT = 3u;
const uint LINK_COUNT_MASK = 7u;
uint node_link(Node n) { return (n.first << LINK_SHIFT) | n.count; }
layout(std430, set = 1, binding = 5) buffer Counters {
    uint cells_lo;          // cells visited, all rays (64 bits: lo, hi)
    uint cells_hi;
    uint max_cells;         // most cells one ray visited
    uint rays_hit;          // rays that entered the mesh
    uint terminated;        // rays stopped by early termination
    uint reentering;        // rays that entered the mesh more than once
    uint bound_hits;        // rays that exhausted the step budget
    uint stalled;           // walks abandoned after STALL cells without progress
    uint fallback_exits;    // exit faces chosen by the fallback rule (rounding)
    uint reversed;          // walks stopped going backwards (flat boundary cells)
    uint walks;             // walks started
    uint entry_searches;    // BVH searches
    uint nodes_visited;     // BVH nodes popped by the searches
    uint faces_tested;      // boundary faces tested by the searches
} counters;

// set 2: the image.
layout(set = 2, binding = 0, rgba32f) uniform writeonly image2D target;

const uint NONE = 0xFFFFFFFFu;
// A boundary face's neighbour when the ray may meet the mesh again after it
// (NONE: a face on the convex hull).
const uint REENTER = 0xFFFFFFFEu;
// Stands for infinity (depths are far below it).
const float INF = 3.0e38;
// Local vertices of face f (opposite vertex f), counter-clockwise seen from
// outside a positively oriented tet (mesh::adjacency::FACE_VERTS).
const uvec3 FACE_VERTS[4] = uvec3[4](uvec3(1, 2, 3), uvec3(0, 3, 2), uvec3(0, 1, 3), uvec3(0, 2, 1));

// The ray: origin, unit direction, the two perturbation directions.
vec3 ray_o;
vec3 ray_d;
vec3 ray_n1;
vec3 ray_n2;

// Vertex offset from the ray origin; the same operations for every cell.
vec3 rel(vec3 p) {
    precise vec3 q = p - ray_o;
    return q;
}

// Edge value w = d . ((p_lo - o) x (p_hi - o)) of the canonically oriented
// edge lo -> hi, and its sign with exact zeros resolved by the perturbation
// o -> o + eps n1 + eps^2 n2 (see reference/raycast.rs, Ray::edge).
// Computed as d . ((p_lo - o) x (p_hi - p_lo)), the same value: the cross
// product of the two offsets from the eye cancels to the edge's length
// times their distance, so for an edge short against that distance (a
// sliver's 1e-4 side seen from 3.4 away: w ~ 1e-6, rounding ~ 1e-6) its
// rounding was the whole value, the face's barycentric weights noise and
// the crossing depth off by up to the face's extent (stress cases slivers
// and needles-caps, 512x512: 2.2e-3 at one pixel each).
vec2 edge_lo_hi(vec3 q_lo, vec3 p_lo, vec3 p_hi) {
    precise vec3 e = p_hi - p_lo;
    precise vec3 c = cross(q_lo, e);
    precise float w = dot(ray_d, c);
    float s = sign(w);
    if (s == 0.0) {
        s = sign(-dot(e, ray_n1));
        if (s == 0.0) {
            s = sign(-dot(e, ray_n2));
        }
    }
    return vec2(w, s);
}

// The edge a -> b (global indices a, b): (value, sign). The canonical
// orientation is chosen by selects, not a branch: lanes of one SIMD vector
// disagree on a < b about half the time, and a branch would run
// edge_lo_hi twice for all of them.
vec2 oriented(uint a, uint b, vec3 qa, vec3 qb, vec3 pa, vec3 pb) {
#ifdef CELL_CONSTANT
    // Constant cells: the cells sharing an edge hold different copies of
    // its points (different indices), so the edge is oriented by position,
    // which the copies share bit for bit.
    bool fwd = pa.x < pb.x || (pa.x == pb.x && (pa.y < pb.y || (pa.y == pb.y && pa.z < pb.z)));
#else
    bool fwd = a < b;
#endif
    vec2 e = edge_lo_hi(fwd ? qa : qb, fwd ? pa : pb, fwd ? pb : pa);
    return fwd ? e : -e;
}

// The crossing of the ray line with the face whose vertex offsets are q and
// barycentric weights bw: (t, scalar); false when unusable (weights summing
// to 0, a face seen edge-on, non-finite results).
bool crossing(vec3 q0, vec3 q1, vec3 q2, vec3 bw, vec3 sv, out vec2 ts) {
    // Edge values scale as length^2 and bw * q as length^3: normalised, so
    // that meshes 1e-15 or 5e14 units across neither underflow nor
    // overflow f32 (stress cases "mesh-scale-*").
    float m = max(abs(bw.x), max(abs(bw.y), abs(bw.z)));
    bw = m > 0.0 ? bw / m : bw;
    float sum = bw.x + bw.y + bw.z;
    vec3 x = bw.x * q0 + bw.y * q1 + bw.z * q2;
    float t = dot(x, ray_d) / sum;
    // The lowest scalar plus weighted differences, kept within the three
    // values (a face of one scalar gives exactly it).
    float lo = min(sv.x, min(sv.y, sv.z));
    float hi = max(sv.x, max(sv.y, sv.z));
    float s = clamp(lo + dot(bw, sv - lo) / sum, lo, hi);
    ts = vec2(t, s);
    return sum != 0.0 && abs(t) < 1e30 && !isnan(t) && !isnan(s);
}

// Whether the ray crosses boundary face `slot` entering the mesh (any way
// for a flat cell, whose orientation says nothing), and where: (t, s).
bool enters(uvec4 face, out vec2 ts) {
    uint v[3] = uint[3](face.y, face.z, face.w);
    vec4 p0 = point_at(v[0]);
    vec4 p1 = point_at(v[1]);
    vec4 p2 = point_at(v[2]);
    vec3 q0 = rel(p0.xyz);
    vec3 q1 = rel(p1.xyz);
    vec3 q2 = rel(p2.xyz);
    bool either_way = face.x < SOLID_BIT;
    vec2 e01 = oriented(v[0], v[1], q0, q1, p0.xyz, p1.xyz);
    if (e01.y == 0.0 || (e01.y > 0.0 && !either_way)) return false;
    vec2 e12 = oriented(v[1], v[2], q1, q2, p1.xyz, p2.xyz);
    if (e12.y != e01.y) return false;
    vec2 e20 = oriented(v[2], v[0], q2, q0, p2.xyz, p0.xyz);
    if (e20.y != e01.y) return false;
    return crossing(q0, q1, q2, vec3(e12.x, e20.x, e01.x), vec3(p0.w, p1.w, p2.w), ts);
}

// (t, id) strictly before (t2, id2) in the order entries are taken.
bool before(float t, uint id, float t2, uint id2) {
    return t < t2 || (t == t2 && id < id2);
}

// 1 / ray_d per axis for the slab test; axis-parallel rays: a tiny
// component instead of 0 keeps the slabs finite.
vec3 inverse_direction() {
    return 1.0 / mix(ray_d, vec3(1e-20), lessThan(abs(ray_d), vec3(1e-20)));
}

// The ray line's parameter span [t_near, t_far] through node `n`'s box
// (t_near > t_far: missed); `inv` from inverse_direction().
vec2 box_span(Node n, vec3 inv) {
    vec3 a = (n.lo - ray_o) * inv;
    vec3 b = (n.hi - ray_o) * inv;
    vec3 tmin3 = min(a, b);
    vec3 tmax3 = max(a, b);
    return vec2(max(tmin3.x, max(tmin3.y, tmin3.z)), min(tmax3.x, min(tmax3.y, tmax3.z)));
}

// Per-ray tallies, added to the counters once per ray.
uint n_cells = 0u;
uint n_nodes = 0u;
uint n_faces = 0u;
uint n_fallback = 0u;
uint n_stalled = 0u;
uint n_reversed = 0u;
bool hit_bound = false;

// Boundary face `face` (a face-list texel) as a candidate for the next
// entry: kept in (t_best, s_best, id_best) when the ray enters the mesh
// through it at t >= t_lo, after (t_prev, id_prev), before the best so far.
void consider(uvec4 face, float t_lo, bool have_prev, float t_prev, uint id_prev, inout float t_best, inout float s_best, inout uint id_best) {
    uint slot = face.x & ~SOLID_BIT;
    n_faces += 1u;
    vec2 ts;
    if (enters(face, ts) && ts.x >= t_lo && (!have_prev || before(t_prev, id_prev, ts.x, slot)) && before(ts.x, slot, t_best, id_best)) {
        t_best = ts.x;
        s_best = ts.y;
        id_best = slot;
    }
}

#ifdef TILE_LISTS
// The faces a ray may enter, per tile of TILE_W x TILE_H pixels of the
// frame's rectangle (tet_raycast/tiles.rs): tile t's are
// tile_faces[tile_first[t] .. tile_first[t + 1]], indices into the face list.
layout(set = 3, binding = 0, r32ui) uniform readonly uimageBuffer tile_first_tb;
layout(set = 3, binding = 1, r32ui) uniform readonly uimageBuffer tile_faces_tb;
// The ray's tile (main).
uint ray_tile;

// The next boundary entry along the ray: the least (t, face) after
// (t_prev, id_prev) (any when !have_prev) with t >= t_lo, among its tile's
// faces, which hold every face it may enter.
bool next_entry(float t_lo, bool have_prev, float t_prev, uint id_prev, out float t_best, out float s_best, out uint id_best) {
    t_best = INF;
    s_best = 0.0;
    id_best = NONE;
    uint first = imageLoad(tile_first_tb, int(ray_tile)).x;
    uint end = imageLoad(tile_first_tb, int(ray_tile) + 1).x;
    for (uint i = first; i < end; ++i) {
        consider(imageLoad(prims_tb, int(imageLoad(tile_faces_tb, int(i)).x)), t_lo, have_prev, t_prev, id_prev, t_best, s_best, id_best);
    }
    return id_best != NONE;
}
#else
// The next boundary entry along the ray: the least (t, face) after
// (t_prev, id_prev) (any when !have_prev) with t >= t_lo. Depth-first
// through the BVH, pruned by the best entry so far: an inner node's two
// children are tested where it is popped and pushed with their near depths,
// the nearer last (popped first) with their links, so each node is fetched
// once (as a child) and a child whose box the ray misses is never pushed.
// The result is the least entry whatever the order; the order only prunes
// sooner.
bool next_entry(float t_lo, bool have_prev, float t_prev, uint id_prev, out float t_best, out float s_best, out uint id_best) {
    vec3 inv = inverse_direction();
    t_best = INF;
    s_best = 0.0;
    id_best = NONE;
    // An entry holds the node's link and count (node_link), not its index:
    // the box was read where the node was pushed, so a pop reads nothing.
    uint stack[48];
    float stack_t[48];
    int sp = 0;
    Node root = node_at(0u);
    vec2 root_span = box_span(root, inv);
    if (root_span.x <= root_span.y && root_span.y >= t_lo) {
        stack[sp] = node_link(root);
        stack_t[sp] = root_span.x;
        sp++;
    }
    while (sp > 0) {
        --sp;
        if (stack_t[sp] > t_best) continue;
        uint first = stack[sp] >> LINK_SHIFT;
        uint count = stack[sp] & LINK_COUNT_MASK;
        n_nodes += 1u;
        if (count == 0u) {
            if (sp + 2 > 48) continue;  // cannot happen: the tree is at most 40 levels deep
            Node l = node_at(first);
            Node r = node_at(first + 1u);
            vec2 sl = box_span(l, inv);
            vec2 sr = box_span(r, inv);
            bool hl = sl.x <= sl.y && sl.y >= t_lo && sl.x <= t_best;
            bool hr = sr.x <= sr.y && sr.y >= t_lo && sr.x <= t_best;
            bool left_first = sl.x <= sr.x;
            // Push the farther child first.
            if (left_first ? hr : hl) {
                stack[sp] = left_first ? node_link(r) : node_link(l);
                stack_t[sp] = left_first ? sr.x : sl.x;
                sp++;
            }
            if (left_first ? hl : hr) {
                stack[sp] = left_first ? node_link(l) : node_link(r);
                stack_t[sp] = left_first ? sl.x : sr.x;
                sp++;
            }
            continue;
        }
        for (uint k = 0u; k < count; ++k) {
            consider(imageLoad(prims_tb, int(first + k)), t_lo, have_prev, t_prev, id_prev, t_best, s_best, id_best);
        }
    }
    return id_best != NONE;
}
#endif

// Front-to-back accumulation: colour and transmittance.
vec3 acc_c = vec3(0.0);
float acc_t = 1.0;

const int WALK_EXIT = 0;
const int WALK_DONE = 1;
const int WALK_TERMINATED = 2;

// Walk from boundary face `face` entered at (t_in, s_in) until the ray leaves
// the mesh (WALK_EXIT, t_exit), is done (far plane, budget, left through a face on the convex hull) or opaque.
//
// The line crosses exactly two faces of a cell. The entry face (a0, a1, a2)
// and its directed edge values (a0->a1, a1->a2, a2->a0), all of sign sigma,
// are carried from the previous cell, so a cell costs one new vertex n (the
// one opposite the entry face) and its three edges n->a_i: the face
// (n, a_{k+1}, a_{k+2}) is crossed iff its three directed edges also have
// sign sigma, i.e. sigma * sign(n->a_{k+1}) > 0 and sigma * sign(n->a_{k+2}) < 0.
// This does not depend on the cell's orientation, so a flat cell (two
// coincident vertices: an edge value exactly 0) is crossed through its
// coincident face with a zero-length segment, as the reference crosses it.
int walk(uint face, float t_in, float s_in, float t_min, float t_max, out float t_exit) {
    uint tet = face >> 2;
    uint f_in = face & 3u;
    uint budget = frame.step_budget;
    uint stall_limit = frame.stall_limit;
    float ert = frame.ert;
    uint stall = 0u;
    t_exit = t_in;
    uvec4 v = tet_at(tet);
    bool solid = v.w >= SOLID_BIT;
    v.w &= ~SOLID_BIT;
    uvec3 fv0 = FACE_VERTS[f_in];
    uint a0 = v[fv0.x];
    uint a1 = v[fv0.y];
    uint a2 = v[fv0.z];
    vec4 p0 = point_at(a0);
    vec4 p1 = point_at(a1);
    vec4 p2 = point_at(a2);
    vec2 e01 = oriented(a0, a1, rel(p0.xyz), rel(p1.xyz), p0.xyz, p1.xyz);
    vec3 ae = vec3(e01.x, oriented(a1, a2, rel(p1.xyz), rel(p2.xyz), p1.xyz, p2.xyz).x, oriented(a2, a0, rel(p2.xyz), rel(p0.xyz), p2.xyz, p0.xyz).x);
    float sigma = e01.y;
    while (true) {
        if (n_cells >= budget) {
            hit_bound = true;
            return WALK_DONE;
        }
        n_cells += 1u;
        // A solid cell entered through a face it reads as an exit (the
        // entry face's outward order, FACE_VERTS, carries sign +1) is being
        // walked backwards (only after a flat boundary cell): stop there, as
        // the reference does.
        if (solid) {
            // (a0, a1, a2) is face f_in in FACE_VERTS's cyclic order iff the
            // permutation (slot of a0, slot of a1, slot of a2, f_in) of the
            // cell's vertices is odd (every FACE_VERTS row with its face
            // index is): the parity by selects, no indexed lookup.
            uint s0 = a0 == v.x ? 0u : (a0 == v.y ? 1u : (a0 == v.z ? 2u : 3u));
            uint s1 = a1 == v.x ? 0u : (a1 == v.y ? 1u : (a1 == v.z ? 2u : 3u));
            uint s2 = a2 == v.x ? 0u : (a2 == v.y ? 1u : (a2 == v.z ? 2u : 3u));
            uint inversions = uint(s0 > s1) + uint(s0 > s2) + uint(s0 > f_in) + uint(s1 > s2) + uint(s1 > f_in) + uint(s2 > f_in);
            bool same_order = (inversions & 1u) == 1u;
            if ((same_order ? sigma : -sigma) > 0.0) {
                n_reversed += 1u;
                t_exit = t_in;
                return WALK_EXIT;
            }
        }
        uint nid = v[f_in];
        vec4 pn = point_at(nid);
        // The offsets from the ray origin are recomputed from the carried
        // points (the same precise subtraction, so the same bits): carrying
        // them too spilled more vectors than the subtractions cost.
        vec3 qn = rel(pn.xyz);
        vec3 q0 = rel(p0.xyz);
        vec3 q1 = rel(p1.xyz);
        vec3 q2 = rel(p2.xyz);
        vec2 e0 = oriented(nid, a0, qn, q0, pn.xyz, p0.xyz);
        vec2 e1 = oriented(nid, a1, qn, q1, pn.xyz, p1.xyz);
        vec2 e2 = oriented(nid, a2, qn, q2, pn.xyz, p2.xyz);
        vec3 c = sigma * vec3(e0.y, e1.y, e2.y);
        vec3 w = vec3(e0.x, e1.x, e2.x);
        bool x0 = c.y > 0.0 && c.z < 0.0;
        bool x1 = c.z > 0.0 && c.x < 0.0;
        bool x2 = c.x > 0.0 && c.y < 0.0;
        // Directed edge values of face k = (n, a_{k+1}, a_{k+2}) as its
        // barycentric weights (a_{k+1}->a_{k+2}, a_{k+2}->n, n->a_{k+1}).
        vec3 b0 = vec3(ae.y, -w.z, w.y);
        vec3 b1 = vec3(ae.z, -w.x, w.z);
        vec3 b2 = vec3(ae.x, -w.y, w.x);
        uint k;
        vec3 bw;
        bool fell_back = int(x0) + int(x1) + int(x2) != 1;
        if (!fell_back) {
            k = x0 ? 0u : (x1 ? 1u : 2u);
            bw = x0 ? b0 : (x1 ? b1 : b2);
        } else {
            // Rounding made the signs inconsistent (a ray within an ulp of a
            // vertex or edge): the face whose worst edge is least wrong, its
            // wrong-signed weights zeroed.
            n_fallback += 1u;
            vec3 s0 = sigma * b0;
            vec3 s1 = sigma * b1;
            vec3 s2 = sigma * b2;
            float m0 = min(s0.x, min(s0.y, s0.z));
            float m1 = min(s1.x, min(s1.y, s1.z));
            float m2 = min(s2.x, min(s2.y, s2.z));
            k = (m0 >= m1 && m0 >= m2) ? 0u : (m1 >= m2 ? 1u : 2u);
            vec3 sk = k == 0u ? s0 : (k == 1u ? s1 : s2);
            bw = max(sk, vec3(0.0)) * sigma;
        }
        vec3 bk = k == 0u ? b0 : (k == 1u ? b1 : b2);
        // The exit face's vertices (n, r1, r2) = (n, a_{k+1}, a_{k+2}); a_k is
        // the vertex it leaves behind.
        uint r0 = k == 0u ? a0 : (k == 1u ? a1 : a2);
        uint r1 = k == 0u ? a1 : (k == 1u ? a2 : a0);
        uint r2 = k == 0u ? a2 : (k == 1u ? a0 : a1);
        vec4 pr1 = k == 0u ? p1 : (k == 1u ? p2 : p0);
        vec4 pr2 = k == 0u ? p2 : (k == 1u ? p0 : p1);
        vec2 ts;
        bool usable = crossing(qn, rel(pr1.xyz), rel(pr2.xyz), bw, vec3(pn.w, pr1.w, pr2.w), ts);
        float t_out = t_in;
        float s_out = s_in;
        if (usable) {
            t_out = max(ts.x, t_in);
            s_out = ts.y;
        }
        if (t_out > t_in) {
            stall = 0u;
            if (t_out > t_min && t_in < t_max) {
                float ta = max(t_in, t_min);
                float tb = min(t_out, t_max);
                float inv_len = 1.0 / (t_out - t_in);
                float sa = ta > t_in ? mix(s_in, s_out, (ta - t_in) * inv_len) : s_in;
                float sb = tb < t_out ? mix(s_in, s_out, (tb - t_in) * inv_len) : s_out;
                if (tb > ta) {
                    vec4 seg = integrate_segment(sa, sb, tb - ta);
                    acc_c += acc_t * seg.rgb;
                    acc_t *= 1.0 - seg.a;
                }
            }
            if (acc_t <= 0.0 || (ert < 1.0 && 1.0 - acc_t >= ert)) {
                return WALK_TERMINATED;
            }
            if (t_out >= t_max) {
                return WALK_DONE;
            }
        } else {
            stall += 1u;
            if (stall > stall_limit) {
                n_stalled += 1u;
                t_exit = t_out;
                return WALK_EXIT;
            }
        }
        // The exit face is the one opposite r0 in this cell.
        uint f_out = v.x == r0 ? 0u : (v.y == r0 ? 1u : (v.z == r0 ? 2u : 3u));
        uint nb = neighbor_at(4u * tet + f_out);
        if (nb >= REENTER) {
            // Out of the mesh. Through a face on its convex hull (NONE) the
            // ray meets no more of it: no entry search (tet_raycast.rs,
            // hull_faces). Not when the exit face was the fallback's
            // choice or the cell is flat: the ray may then be leaving
            // through another face.
            t_exit = t_out;
            return nb == NONE && solid && !fell_back ? WALK_DONE : WALK_EXIT;
        }
        a0 = nid;
        a1 = r1;
        a2 = r2;
        p0 = pn;
        p1 = pr1;
        p2 = pr2;
        ae = vec3(bk.z, bk.x, bk.y);
        tet = nb >> 2;
        f_in = nb & 3u;
        t_in = t_out;
        s_in = s_out;
        v = tet_at(tet);
        solid = v.w >= SOLID_BIT;
        v.w &= ~SOLID_BIT;
#ifdef CELL_CONSTANT
        // Constant cells (src/mesh/cell_data.rs): every tet has its own
        // copies of the points, holding its value. The carried face is
        // renamed to this cell's copies, found by position (copies are bit
        // for bit the same points), and takes this cell's value, so the
        // segment is constant and the vertex tests below see this cell's
        // indices. (Edges are oriented by position: `oriented`.)
        {
            uvec3 fn_ = FACE_VERTS[f_in];
            uint c0 = v[fn_.x];
            uint c1 = v[fn_.y];
            uint c2 = v[fn_.z];
            vec3 x0 = point_at(c0).xyz;
            vec3 x1 = point_at(c1).xyz;
            a0 = all(equal(x0, p0.xyz)) ? c0 : (all(equal(x1, p0.xyz)) ? c1 : c2);
            a1 = all(equal(x0, p1.xyz)) ? c0 : (all(equal(x1, p1.xyz)) ? c1 : c2);
            a2 = all(equal(x0, p2.xyz)) ? c0 : (all(equal(x1, p2.xyz)) ? c1 : c2);
            float value = point_at(v.x).w;
            p0.w = value;
            p1.w = value;
            p2.w = value;
            s_in = value;
        }
#endif
    }
    return WALK_DONE;
}

void main() {
    ivec2 size = imageSize(target);
    // The dispatch covers the rectangle (the boundary's projected box) from
    // its corner; outside it no ray meets the mesh, and tet_raycast.rs
    // cleared those pixels.
    // Workgroup rows interleaved over the device's runs of workgroups
    // (common/dispatch.glsl).
    // Padding rows (row >= rows) lie below the rectangle: the test below.
#ifdef ADAPTIVE
    uint pass_step = frame.cast_step;
    uvec2 at;
    if (!adaptive_point(pass_step, frame.rect, frame.rows, frame.runs, at)) return;
    ivec2 px = ivec2(at + frame.rect.xy);
    if (!adaptive_in_rect(frame.rect, at)) {
        // Lattice padding past the rectangle: no ray meets the mesh there.
        adaptive_store(pass_step, frame.rect, at, vec4(0.0), 0u, false);
        return;
    }
#else
    uvec2 at = uvec2(gl_WorkGroupID.x, interleaved_row(frame.rows, frame.runs)) * uvec2(WG_X, WG_Y) + gl_LocalInvocationID.xy;
    ivec2 px = ivec2(at + frame.rect.xy);
    if (px.x >= size.x || px.y >= size.y || uint(px.x) > frame.rect.z || uint(px.y) > frame.rect.w) return;
#endif
#ifdef TILE_LISTS
    uint tiles_x = (frame.rect.z - frame.rect.x + uint(TILE_W)) / uint(TILE_W);
    ray_tile = at.y / uint(TILE_H) * tiles_x + at.x / uint(TILE_W);
#endif
    // The ray through the pixel's centre (scene::Camera::ray), relative to
    // the render origin.
    vec2 ndc = (vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0;
    vec3 fwd = frame.forward;
    float cos_fwd;
    if (frame.perspective > 0.5) {
        ray_o = frame.eye;
        ray_d = normalize(fwd + frame.right * ndc.x - frame.up * ndc.y);
        cos_fwd = dot(ray_d, fwd);
    } else {
        ray_o = frame.eye + frame.right * ndc.x - frame.up * ndc.y;
        ray_d = fwd;
        cos_fwd = 1.0;
    }
    // n1, n2: an orthonormal pair perpendicular to d (Ray::new's choice).
    vec3 ad = abs(ray_d);
    vec3 ax = (ad.x <= ad.y && ad.x <= ad.z) ? vec3(1, 0, 0) : (ad.y <= ad.z ? vec3(0, 1, 0) : vec3(0, 0, 1));
    ray_n1 = normalize(cross(ray_d, ax));
    ray_n2 = cross(ray_d, ray_n1);
    // Segments are clipped to the view depths [near, far].
    float t_min = frame.near / cos_fwd;
    float t_max = frame.far / cos_fwd;
    float tol = frame.entry_tol;

    bool have_prev = false;
    float t_prev = -INF;
    uint id_prev = NONE;
    float t_done = -INF;
    uint walks = 0u;
    uint searches = 0u;
    bool terminated = false;
    // A ray whose line meets the mesh's box only outside [t_min, t_max]
    // (behind the eye, beyond the far plane) has nothing to integrate: skip
    // the search and the walk through cells it would clip away (a view
    // turned away from the mesh walked every cell behind the eye). The
    // margin keeps a box ending within f32 rounding of a clip depth.
    vec2 root = box_span(node_at(0u), inverse_direction());
    bool in_depth = root.y >= t_min - 1e-4 * abs(t_min) && root.x <= t_max + 1e-4 * abs(t_max);
    while (in_depth) {
        float t_e;
        float s_e;
        uint id_e;
        searches += 1u;
        // An entry up to the tolerance (plus a few f32 ulps of the depth)
        // before the last exit still counts: coincident boundaries (seams)
        // give the exit and the re-entry the same depth up to rounding.
        float t_lo = have_prev ? t_done - (tol + 1e-5 * abs(t_done)) : -INF;
        if (!next_entry(t_lo, have_prev, t_prev, id_prev, t_e, s_e, id_e)) break;
        if (t_e >= t_max) break;
        have_prev = true;
        t_prev = t_e;
        id_prev = id_e;
        walks += 1u;
        float t_exit;
        int end = walk(id_e, t_e, s_e, t_min, t_max, t_exit);
        if (end == WALK_TERMINATED) {
            terminated = true;
            break;
        }
        if (end == WALK_DONE) break;
        t_done = t_exit;
    }
    vec4 colour = vec4(acc_c, 1.0 - acc_t);
#ifdef ADAPTIVE
    adaptive_store(pass_step, frame.rect, at, colour, walks, true);
    adaptive_pixel(frame.rect, at, colour);
#else
    imageStore(target, px, colour);
#endif

    if (n_cells > 0u) {
        uint old = atomicAdd(counters.cells_lo, n_cells);
        if (old > 0xFFFFFFFFu - n_cells) atomicAdd(counters.cells_hi, 1u);
        atomicMax(counters.max_cells, n_cells);
    }
    if (walks > 0u) {
        atomicAdd(counters.rays_hit, 1u);
        atomicAdd(counters.walks, walks);
    }
    if (walks > 1u) atomicAdd(counters.reentering, 1u);
    if (terminated) atomicAdd(counters.terminated, 1u);
    if (hit_bound) atomicAdd(counters.bound_hits, 1u);
    if (n_stalled > 0u) atomicAdd(counters.stalled, n_stalled);
    if (n_fallback > 0u) atomicAdd(counters.fallback_exits, n_fallback);
    if (n_reversed > 0u) atomicAdd(counters.reversed, n_reversed);
    atomicAdd(counters.entry_searches, searches);
    if (n_nodes > 0u) atomicAdd(counters.nodes_visited, n_nodes);
    if (n_faces > 0u) atomicAdd(counters.faces_tested, n_faces);
}
