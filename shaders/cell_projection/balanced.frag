#version 450
// Balanced cell projection's fragment stage (also resident's): the nearest
// of the tet's known exit planes, the segment stopped at the far plane
// (known_exit), integrated. The plane of the face being drawn is an entry plane, never
// in the mask.
#include "common/frame.glsl"
#include "common/integrate.glsl"
#include "common/clip.glsl"
#define EXIT_VEC vec4
#define EXIT_N 4
#include "common/exit.glsl"
#include "cell_projection/known_exits_io.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    out_color = segment_color();
#ifdef EXTRA_WORK
    // Test-only deliberate cost (VOLBENCH_TEST_EXTRA_FRAGMENT_WORK,
    // docs/tracking.md): a chain of EXTRA_WORK dependent multiply-adds the
    // compiler can neither drop nor unroll. The trip count is EXTRA_WORK plus
    // a term that is 0 for every fragment drawn (its depth lies in [0, 1])
    // but unknown when compiling, so the loop is a real loop at every N and
    // its cost grows linearly with N (a constant bound was unrolled up to 32
    // steps and became a far costlier loop beyond).
    int steps = EXTRA_WORK + int(gl_FragCoord.z < -1.0);
    float w = out_color.a + gl_FragCoord.x;
    for (int i = 0; i < steps; i++) {
        w = w * 1.0000001 + 1e-9;
    }
    if (w == -1.0) {
        out_color.r += 1e-7;
    }
#endif
}
