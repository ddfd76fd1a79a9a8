#version 450 core
// The 12 edges of one axis-aligned box per instance, as 24 line endpoints made from
// gl_VertexID: no vertex buffer.
struct Box {
    vec4 lo;
    vec4 hi;
    vec4 colour;
};
layout(std430, binding = 2) readonly buffer Boxes { Box boxes[]; };

layout(location = 0) uniform mat4 view_proj;

flat out vec3 box_colour;

// Corner c of a box: bit 0 = x, bit 1 = y, bit 2 = z (0 = lo, 1 = hi).
const int kEdges[24] = int[24](0, 1, 2, 3, 4, 5, 6, 7,   // along x
                              0, 2, 1, 3, 4, 6, 5, 7,   // along y
                              0, 4, 1, 5, 2, 6, 3, 7);  // along z

void main() {
    Box b = boxes[gl_InstanceID];
    int c = kEdges[gl_VertexID];
    vec3 p = vec3((c & 1) != 0 ? b.hi.x : b.lo.x, (c & 2) != 0 ? b.hi.y : b.lo.y, (c & 4) != 0 ? b.hi.z : b.lo.z);
    box_colour = b.colour.rgb;
    gl_Position = view_proj * vec4(p, 1.0);
}
