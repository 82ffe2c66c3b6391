// Object view, vertex stage. GEOMETRY_REFERENCE: a full-screen triangle over the
// reference view's unit sphere (the fragment stage intersects it exactly); otherwise a mesh.
#ifdef GEOMETRY_REFERENCE
out vec2 v_ndc;
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    v_ndc = p;
    gl_Position = vec4(p, 0.0, 1.0);
}
#else
in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
uniform mat4 u_view_projection;
uniform mat4 u_model;
out vec3 v_position;
out vec3 v_normal;
out vec3 v_tangent;
#ifdef SH_VERTEX_LIGHT
in int in_vertex;        // the vertex's index (an attribute: moderngl mishandles gl_VertexID)
flat out int v_vertex;   // which vertex's transferred (shadowed) lighting to use
#endif
void main() {
#ifdef SH_VERTEX_LIGHT
    v_vertex = in_vertex;
#endif
    vec4 world = u_model * vec4(in_position, 1.0);
    v_position = world.xyz;
    v_normal = mat3(u_model) * in_normal;
    v_tangent = mat3(u_model) * in_tangent;
    gl_Position = u_view_projection * world;
}
#endif
