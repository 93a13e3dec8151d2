// How a segment's scalars and length index the transfer-function and
// integration tables (common/integrate.glsl reads `frame.table`): a member
// of the push-constant block of every shader that integrates cells,
// common/frame.glsl (cell projection) and tet_raycast/frame.glsl.
// Rust: algo::integrate::TableMap (the reflection test checks the two).
#ifndef TABLE_MAP_GLSL
#define TABLE_MAP_GLSL
struct TableMap {
    float tf_lo;          // lowest tabulated scalar (mapped as the cells' scalars are)
    float tf_inv_range;   // 1 / (highest - lowest)
    float tf_entries;     // entries of the transfer-function table
    float table_side;     // side of the integration table
    float preint_length;  // length scale of the pre-integration table
};
#endif
