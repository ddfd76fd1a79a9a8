#version 450 core
#extension GL_ARB_shader_draw_parameters : require
// One vertex of an object's mesh, in the mesh's own coordinates; the object and its depth
// floor come from per-draw attributes (divisor 1, read at the draw's base instance), so one
// multi-draw call draws many objects.
layout(location = 0) in vec3 position;
layout(location = 1) in uint object_id;
layout(location = 2) in float object_depth_floor;

layout(std430, binding = 0) readonly buffer ObjectWorld { mat4 world[]; };
layout(std430, binding = 1) readonly buffer ObjectColour { vec4 colour[]; };
// Per object, where its mesh's vertex colours start in VertexColour (0xFFFFFFFF: none); a drawn
// LOD is a prefix of its mesh's vertices, so vertex gl_VertexID - gl_BaseVertexARB of the draw is
// the mesh's vertex of that number. Colours are RGBA8, sRGB.
layout(std430, binding = 3) readonly buffer ItemVertexColour { uint colour_first[]; };
layout(std430, binding = 4) readonly buffer VertexColour { uint vertex_colour[]; };
// Laid out as VertexColour: an HLOD vertex's normal, octahedral snorm16x2 (0: none).
layout(std430, binding = 5) readonly buffer VertexNormal { uint vertex_normal[]; };

layout(location = 0) uniform mat4 view_proj;
layout(location = 1) uniform vec3 eye;
// The reference's tie pass (FrameDisplay): each vertex moves this fraction of its distance
// towards the eye, so its pixel stays and its depth comes nearer by as much as that pixel's
// share of the fraction spans there; 0 in every other draw.
layout(location = 2) uniform float tie_pull;

out vec3 world_position;
out vec3 base_colour;
// The vertex's normal in world space, turned to the eye (lighting is two-sided, and so the three
// of a triangle interpolate without cancelling), and 1; or 0 and 0 for a vertex without one.
out vec3 vertex_normal_world;
out float normal_weight;
flat out uint item;
flat out float depth_floor;

void main() {
    vec4 p = world[object_id] * vec4(position, 1.0);
    world_position = p.xyz;
    vec3 c = colour[object_id].rgb;
    const uint first = colour_first[object_id];
    vertex_normal_world = vec3(0.0);
    normal_weight = 0.0;
    if (first != 0xFFFFFFFFu) {
        const uint at = first + uint(gl_VertexID - gl_BaseVertexARB);
        const vec3 v = unpackUnorm4x8(vertex_colour[at]).rgb;
        c *= mix(v / 12.92, pow((v + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), v));
        const uint code = vertex_normal[at];
        if (code != 0u) {
            const vec2 o = unpackSnorm2x16(code);
            vec3 n = vec3(o, 1.0 - abs(o.x) - abs(o.y));
            if (n.z < 0.0) n.xy = (1.0 - abs(n.yx)) * vec2(o.x >= 0.0 ? 1.0 : -1.0, o.y >= 0.0 ? 1.0 : -1.0);
            n = normalize(mat3(world[object_id]) * n);
            vertex_normal_world = dot(n, eye - p.xyz) < 0.0 ? -n : n;
            normal_weight = 1.0;
        }
    }
    base_colour = c;
    item = object_id + 1u;  // 0 = background in the item buffer
    depth_floor = tie_pull > 0.0 ? 0.0 : object_depth_floor;
    gl_Position = view_proj * vec4(mix(p.xyz, eye, tie_pull), 1.0);
}
