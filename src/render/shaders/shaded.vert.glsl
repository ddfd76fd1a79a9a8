#version 450 core
// One vertex of an object's mesh, in the mesh's own coordinates; the object and its depth
// floor come from per-draw attributes (divisor 1, read at the draw's base instance), so one
// multi-draw call draws many objects.
layout(location = 0) in vec3 position;
layout(location = 1) in uint object_id;
layout(location = 2) in float object_depth_floor;

layout(std430, binding = 0) readonly buffer ObjectWorld { mat4 world[]; };
layout(std430, binding = 1) readonly buffer ObjectColour { vec4 colour[]; };

layout(location = 0) uniform mat4 view_proj;

out vec3 world_position;
flat out vec3 base_colour;
flat out uint item;
flat out float depth_floor;

void main() {
    vec4 p = world[object_id] * vec4(position, 1.0);
    world_position = p.xyz;
    base_colour = colour[object_id].rgb;
    item = object_id + 1u;  // 0 = background in the item buffer
    depth_floor = object_depth_floor;
    gl_Position = view_proj * p;
}
