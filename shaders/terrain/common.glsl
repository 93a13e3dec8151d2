// Push constants of every terrain pipeline (112 bytes).
layout(push_constant) uniform Push {
    mat4 view_proj;
    // rgb: the class colour (NC / PC tessellation / TIN); a: 1 to tint by
    // class, 0 for the height colours.
    vec4 tint;
    // xyz: unit direction towards the light; w unused.
    vec4 light;
    // x, y: lowest and highest height.
    vec4 range;
} pc;
