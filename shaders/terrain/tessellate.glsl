// The tessellation of one PC cell: a line-by-line transcription of
// `HybridModel::tessellate` and `hybrid::ear_clip` (src/terrain/hybrid.rs),
// in the same f32 arithmetic and order, so GPU and CPU emit the same
// triangles in the same order. Tables: `algo::terrain::tables`.
//
// The includer declares, before including:
//   void emit_triangle(uint a, uint b, uint c);   // geometry indices
//   uint tess_grid_base();  uint tess_grid_width();
// and binds the TB coordinates (RG32F) and chains (RGBA32UI) below.
// `tessellate` returns false when a ring has no ear and no flat vertex
// (what the CPU reports as an error), having emitted what it could.

#define MAX_CHAINS 8
#define MAX_ENDS 16
#define MAX_RING 256
#define FLAT_AREA 1e-4

layout(set = 0, binding = TESS_BINDING) uniform samplerBuffer tb_xy;
layout(set = 0, binding = TESS_BINDING + 1) uniform usamplerBuffer chain_list;

float cross2(vec2 o, vec2 a, vec2 b) {
    precise float p = (a.x - o.x) * (b.y - o.y);
    precise float q = (a.y - o.y) * (b.x - o.x);
    precise float r = p - q;
    return r;
}

// (start, len, patch TB start, patch TB length)
uint tb_at(uvec4 ch, uint k) {
    return ch.z + (ch.x - ch.z + k) % ch.w;
}

vec2 tess_origin;
float tess_side;

vec2 tb_local(uint t) {
    precise vec2 p = texelFetch(tb_xy, int(t)).xy - tess_origin;
    return p;
}

float border_u(vec2 p) {
    float s = tess_side;
    precise float u;
    if (p.y == 0.0) {
        u = p.x;
    } else if (p.x == s) {
        u = s + p.y;
    } else if (p.y == s) {
        u = 2.0 * s + (s - p.x);
    } else {
        u = 3.0 * s + (s - p.y);
    }
    return u;
}

uint ring_id[MAX_RING];
vec2 ring_p[MAX_RING];
int ring_n;

void ring_push(uint id, vec2 p) {
    if (ring_n < MAX_RING) {
        ring_id[ring_n] = id;
        ring_p[ring_n] = p;
    }
    ring_n++;
}

bool ear_clip() {
    if (ring_n > MAX_RING) {
        return false;
    }
    while (ring_n > 3) {
        int n = ring_n;
        int clip = -1;
        for (int k = 0; k < n && clip < 0; k++) {
            int a = (k + n - 1) % n, c = (k + 1) % n;
            if (cross2(ring_p[a], ring_p[k], ring_p[c]) <= 0.0) {
                continue;
            }
            bool blocked = false;
            for (int o = 0; o < n && !blocked; o++) {
                if (o != a && o != k && o != c) {
                    vec2 p = ring_p[o];
                    blocked = cross2(ring_p[a], ring_p[k], p) >= 0.0 && cross2(ring_p[k], ring_p[c], p) >= 0.0
                        && cross2(ring_p[c], ring_p[a], p) >= 0.0;
                }
            }
            if (!blocked) {
                clip = k;
            }
        }
        if (clip < 0) {
            for (int k = 0; k < n && clip < 0; k++) {
                if (abs(cross2(ring_p[(k + n - 1) % n], ring_p[k], ring_p[(k + 1) % n])) <= FLAT_AREA) {
                    clip = k;
                }
            }
        }
        if (clip < 0) {
            return false;
        }
        emit_triangle(ring_id[(clip + n - 1) % n], ring_id[clip], ring_id[(clip + 1) % n]);
        for (int k = clip; k + 1 < n; k++) {
            ring_id[k] = ring_id[k + 1];
            ring_p[k] = ring_p[k + 1];
        }
        ring_n = n - 1;
    }
    if (ring_n == 3) {
        emit_triangle(ring_id[0], ring_id[1], ring_id[2]);
    }
    return true;
}

// `entry`: the cell's table entry (see algo::terrain::tables).
bool tessellate(uvec4 entry) {
    uvec2 cell = uvec2(entry.x & 0xffffu, entry.x >> 16);
    uint side = entry.z & 0xffu;
    uint first_chain = entry.y & 0xffffffu;
    int nchains = int(entry.y >> 24);
    float s = float(side);
    tess_side = s;
    tess_origin = vec2(float(cell.x * side), float(cell.y * side));
    uint gw = tess_grid_width(), gb = tess_grid_base();
    uint corner_id[4] = uint[4](gb + cell.x * side + gw * (cell.y * side), gb + (cell.x + 1u) * side + gw * (cell.y * side),
        gb + (cell.x + 1u) * side + gw * ((cell.y + 1u) * side), gb + cell.x * side + gw * ((cell.y + 1u) * side));
    vec2 corner_xy[4] = vec2[4](vec2(0.0), vec2(s, 0.0), vec2(s, s), vec2(0.0, s));
    if (nchains > MAX_CHAINS) {
        return false;
    }
    // Chain ends sorted by u (insertion, as the CPU).
    float end_u[MAX_ENDS];
    int end_chain[MAX_ENDS];
    bool end_start[MAX_ENDS];
    int m = 0;
    for (int ci = 0; ci < nchains; ci++) {
        uvec4 ch = texelFetch(chain_list, int(first_chain) + ci);
        for (int e = 0; e < 2; e++) {
            float u = border_u(tb_local(tb_at(ch, e == 0 ? 0u : ch.y - 1u)));
            int at = m;
            while (at > 0 && end_u[at - 1] > u) {
                end_u[at] = end_u[at - 1];
                end_chain[at] = end_chain[at - 1];
                end_start[at] = end_start[at - 1];
                at--;
            }
            end_u[at] = u;
            end_chain[at] = ci;
            end_start[at] = e == 0;
            m++;
        }
    }
    bool visited[MAX_ENDS];
    for (int i = 0; i < m; i++) {
        visited[i] = false;
    }
    bool ok = true;
    for (int start = 0; start < m; start++) {
        if (visited[start] || !end_start[start]) {
            continue;
        }
        ring_n = 0;
        int i = start;
        for (int guard = 0; guard <= m; guard++) {
            visited[i] = true;
            uvec4 ch = texelFetch(chain_list, int(first_chain) + end_chain[i]);
            uint first = tb_at(ch, 0u);
            ring_push(first, tb_local(first));
            float ua = end_u[i];
            precise float ub = end_u[(i + 1) % m];
            if (ub <= ua) {
                ub += 4.0 * s;
            }
            for (int round = 0; round < 2; round++) {
                for (int c = 0; c < 4; c++) {
                    precise float cu = float(c) * s + float(round) * 4.0 * s;
                    if (cu > ua && cu < ub) {
                        ring_push(corner_id[c], corner_xy[c]);
                    }
                }
            }
            int j = (i + 1) % m;
            if (end_start[j]) {
                return false;
            }
            ch = texelFetch(chain_list, int(first_chain) + end_chain[j]);
            for (uint k = ch.y - 1u; k >= 1u; k--) {
                uint t = tb_at(ch, k);
                ring_push(t, tb_local(t));
            }
            int next = -1;
            for (int e = 0; e < m && next < 0; e++) {
                if (end_chain[e] == end_chain[j] && end_start[e]) {
                    next = e;
                }
            }
            i = next;
            if (i == start) {
                break;
            }
            if (i < 0 || visited[i]) {
                return false;
            }
        }
        ok = ear_clip() && ok;
    }
    return ok;
}
