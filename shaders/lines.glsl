// Axes and the incident direction: coloured line segments.
#ifdef VERTEX
in vec3 in_position;
in vec3 in_color;
uniform mat4 u_view_projection;
out vec3 v_color;
void main() { v_color = in_color; gl_Position = u_view_projection * vec4(in_position, 1.0); }
#else
in vec3 v_color;
out vec4 frag;
void main() { frag = vec4(v_color, 1.0); }
#endif
