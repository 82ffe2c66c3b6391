// Object view, fragment stage: shading frame, then one lighting mode.
//   MODE_POINT: directional light, f(wi, wo) · max(0, n·L)
//   MODE_FIS:   filtered importance sampling of an HDR lat-long map (Colbert & Křivánek)
//   MODE_SH:    spherical harmonics (shaders/sh.glsl), unclamped so negative ringing is seen
//   MODE_PREFILTERED: the split sum (shaders/prefiltered.glsl)
// Outputs the sum over this batch's samples (FIS) so batches add up in a float target.
#ifdef GEOMETRY_REFERENCE
in vec2 v_ndc;
#else
in vec3 v_position;
in vec3 v_normal;
in vec3 v_tangent;
uniform vec3 u_camera_position;
uniform bool u_mesh_tangents;
#endif
out vec4 frag;

uniform vec3 u_light_direction;   // world, towards the light
uniform vec3 u_light_color;
uniform sampler2D u_env;
uniform vec2 u_env_size;
uniform float u_env_max_lod;
uniform float u_env_rotation;     // radians about +Y
uniform sampler2D u_samples;      // (u1, u2, lobe, 0) per sample, row by row
uniform int u_sample_row;          // samples per texture row (GL caps a row's width)
uniform int u_sample_begin;
uniform int u_sample_end;
uniform float u_set_size;         // samples in the whole set (for the filter footprint)

vec2 env_uv(vec3 d) { return env_uv(d, u_env_rotation); }

void main() {
#ifdef GEOMETRY_REFERENCE
    float r2 = dot(v_ndc, v_ndc);
    if (r2 > 1.0) { frag = vec4(0.0); return; }
    vec3 n = vec3(v_ndc, sqrt(1.0 - r2));
    vec3 wo_world = vec3(0.0, 0.0, 1.0);
#else
    vec3 n = normalize(v_normal);
    vec3 wo_world = normalize(u_camera_position - v_position);
    if (dot(n, wo_world) < 0.0) n = -n;  // two-sided
#endif
#if defined(GEOMETRY_REFERENCE)
    vec3 tx = vec3(1.0, 0.0, 0.0) - n.x * n;
    vec3 t = length(tx) > 1e-6 ? normalize(tx) : normalize(vec3(0.0, 0.0, 1.0) - n.z * n);
#else
    // anisotropic materials follow the mesh's tangents; isotropic ones use the smooth
    // projected +X, so that shared sample sets do not change pattern across UV charts
    vec3 along = u_mesh_tangents ? v_tangent : vec3(1.0, 0.0, 0.0);
    vec3 tx = along - dot(along, n) * n;
    vec3 t = length(tx) > 1e-6 ? normalize(tx) : normalize(vec3(0.0, 0.0, 1.0) - n.z * n);
#endif
    vec3 b = cross(n, t);
    mat3 to_world = mat3(t, b, n);
    vec3 wo = vec3(dot(wo_world, t), dot(wo_world, b), dot(wo_world, n));
    vec3 color = vec3(0.0);
#ifdef MODE_POINT
    vec3 L = normalize(u_light_direction);
    vec3 wi = vec3(dot(L, t), dot(L, b), dot(L, n));
    color = material_eval(wi, wo) * max(0.0, dot(n, L)) * u_light_color;
#endif
#ifdef MODE_FIS
    float texel = 2.0 * PI * PI / (u_env_size.x * u_env_size.y);  // solid angle per texel / sin θ
    for (int i = u_sample_begin; i < u_sample_end; i++) {
        vec4 s = texelFetch(u_samples, ivec2(i % u_sample_row, i / u_sample_row), 0);
        vec3 wi = material_sample(int(s.z), wo, s.xy);
        if (wi.z <= 0.0) continue;
        float pdf = material_pdf(wi, wo);
        if (!(pdf > 0.0)) continue;
        vec3 d = to_world * wi;
        float omega_s = 1.0 / (u_set_size * pdf);
        float omega_p = texel * max(sqrt(max(0.0, 1.0 - d.y * d.y)), 1e-4);
        float lod = clamp(0.5 * log2(omega_s / omega_p) + 1.0, 0.0, u_env_max_lod);
        vec3 radiance = textureLod(u_env, env_uv(d), lod).rgb;
        color += material_eval(wi, wo) * wi.z * radiance / pdf;
    }
#endif
#ifdef MODE_SH
    color = sh_shade(mat3(t, b, n), wo);  // mat3 columns = the rows of world → local
#endif
#ifdef MODE_PREFILTERED
    color = prefiltered_shade(to_world, n, wo);
#endif
    frag = vec4(color, 1.0);
}
