// Push constants of every terrain pipeline but hm-compute's pass.
// Rust: algo::terrain::Push (the reflection test checks the two).
layout(push_constant) uniform Push {
    mat4 view_proj;
    vec3 tint;          // the class colour (NC / PC tessellation / TIN)
    float tint_mix;     // 1 to tint by class, 0 for the height colours
    vec3 light;         // unit direction towards the light
    float height_lo;    // lowest and highest height
    float height_hi;
    uint grid_base;     // terrain/tessellate.glsl's grid (hm-gpu's geometry shader)
    uint grid_width;
} pc;
