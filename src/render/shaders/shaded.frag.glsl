#version 450 core
// Headlight shading from the face normal (screen-space derivatives of the world position, so
// no normals are stored or streamed), both sides lit: CAD meshes are often open. An HLOD's
// triangle whose three vertices carry the normals of the full detail they stand for is lit by
// their interpolation instead, where it is within 60 degrees of the face's. base_colour is
// linear (glTF's baseColorFactor is); lighting happens in linear light and the result is written
// sRGB-encoded, as a glTF viewer shows it.
in vec3 world_position;
in vec3 base_colour;
in vec3 vertex_normal_world;
in float normal_weight;
flat in uint item;
// The window depth of the object's box's nearest point (0 when the box reaches the near
// plane). No surface of the object is nearer, but a rasteriser interpolating depth at a pixel
// centre just outside a thin sliver triangle extrapolates its plane (llvmpipe was seen 1e-3
// nearer than every vertex, at depth 0.998): such a fragment is put back at the box's depth.
flat in float depth_floor;

layout(location = 1) uniform vec3 eye;

layout(depth_greater) out float gl_FragDepth;

layout(location = 0) out vec4 frag_colour;
layout(location = 1) out uint frag_item;

vec3 linearToSrgb(vec3 c) {
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
    vec3 n = normalize(cross(dFdx(world_position), dFdy(world_position)));
    if (normal_weight > 0.999) {
        const vec3 smooth_n = normalize(vertex_normal_world);
        if (abs(dot(smooth_n, n)) > 0.5) n = smooth_n;
    }
    vec3 to_eye = normalize(eye - world_position);
    float lambert = abs(dot(n, to_eye));
    frag_colour = vec4(linearToSrgb(base_colour * (0.2 + 0.8 * lambert)), 1.0);
    frag_item = item;
    gl_FragDepth = max(gl_FragCoord.z, depth_floor);
}
