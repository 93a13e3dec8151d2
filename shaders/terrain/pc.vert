#version 450
// GPU HM: the PC list is the vertex input, one PC-list entry per vertex
// (algo::terrain::tables); the geometry shader tessellates it.
layout(location = 0) in uvec4 entry;
layout(location = 0) out flat uvec4 v_entry;

void main() {
    v_entry = entry;
}
