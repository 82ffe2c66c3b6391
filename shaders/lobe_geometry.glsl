// Face normals of the displaced lobe, for shading.
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec3 g_position[];
out vec3 f_normal;
out vec3 f_position;
void main() {
    vec3 n = cross(g_position[1] - g_position[0], g_position[2] - g_position[0]);
    float len = length(n);
    n = len > 1e-20 ? n / len : vec3(0.0, 0.0, 1.0);
    for (int i = 0; i < 3; i++) {
        f_normal = n;
        f_position = g_position[i];
        gl_Position = gl_in[i].gl_Position;
        EmitVertex();
    }
    EndPrimitive();
}
