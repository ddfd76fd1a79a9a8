#version 450 core
// Headlight shading from the face normal (screen-space derivatives of the world position, so
// no normals are stored or streamed), both sides lit: CAD meshes are often open.
in vec3 world_position;
flat in vec3 base_colour;
flat in uint item;

layout(location = 1) uniform vec3 eye;

layout(location = 0) out vec4 frag_colour;
layout(location = 1) out uint frag_item;

void main() {
    vec3 n = normalize(cross(dFdx(world_position), dFdy(world_position)));
    vec3 to_eye = normalize(eye - world_position);
    float lambert = abs(dot(n, to_eye));
    frag_colour = vec4(base_colour * (0.2 + 0.8 * lambert), 1.0);
    frag_item = item;
}
