#version 450 core
flat in vec3 box_colour;
layout(location = 0) out vec4 frag_colour;
void main() { frag_colour = vec4(box_colour, 1.0); }
