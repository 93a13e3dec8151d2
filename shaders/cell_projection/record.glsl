// The last float of a balanced-family vertex record (balanced.rs,
// `CODE_EXITS_SHIFT`): i | exits << 2 | flags << 6 | piece << 8, exact in
// f32. i: the vertex's index in its tet; exits: bit k set when the plane
// opposite vertex k is an exit plane for every ray through the tet (see
// exit_point_known in common/exit.glsl); flags and piece: atfs's interval.

int record_code(float code) {
    return int(code + 0.5);
}
int record_vertex(int code) {
    return code & 3;
}
uint record_exits(int code) {
    return uint(code >> 2) & 15u;
}
int record_flags(int code) {
    return (code >> 6) & 3;
}
int record_piece(int code) {
    return code >> 8;
}
