// The object view's shading frames, one pixel at a time (render/gbuffer.py): what the object
// fragment stage computes before it lights a pixel, written out for the image metric (the
// frame follows the mesh's tangents: any frame gives an isotropic material the same image).
in vec3 v_position;
in vec3 v_normal;
in vec3 v_tangent;
uniform vec3 u_camera_position;
layout(location = 0) out vec4 out_normal;   // xyz, and w = 1 where the object is
layout(location = 1) out vec4 out_tangent;
layout(location = 2) out vec4 out_view;     // towards the camera

void main() {
    vec3 n = normalize(v_normal);
    vec3 wo_world = normalize(u_camera_position - v_position);
    if (dot(n, wo_world) < 0.0) n = -n;  // two-sided, as object_fragment.glsl
    vec3 tx = v_tangent - dot(v_tangent, n) * n;
    vec3 t = length(tx) > 1e-6 ? normalize(tx) : normalize(vec3(0.0, 0.0, 1.0) - n.z * n);
    out_normal = vec4(n, 1.0);
    out_tangent = vec4(t, 1.0);
    out_view = vec4(wo_world, 1.0);
}
