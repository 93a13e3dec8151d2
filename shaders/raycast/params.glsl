// The ray casters' static parameters (set 0, binding 0; uploaded once).
// Rust: algo::raycast::Params (the reflection test checks the two).
layout(std140, set = 0, binding = 0) uniform Params {
    vec3 box_max;          // dims - 1: the box in voxel coordinates
    float brick;           // brick edge in voxels
    vec3 inv_dims;         // 1 / dims
    float table_entries;   // entries of the table (1D transfer function, or the PREINT table's side)
    vec3 spacing;          // world units per voxel
    float step;            // largest step in voxels (option `step`)
    float tf_scale;        // normalised texel v -> table coordinate t = tf_scale * (v - tf_offset)
    float tf_offset;
    float ert;             // early-termination threshold
    float preint_length;   // world length the PREINT table is built for
    vec3 brick_grid;       // bricks along each axis
    float ambient;         // Blinn-Phong (SHADE)
    float diffuse;
    float specular;
    float shininess;
} params;
