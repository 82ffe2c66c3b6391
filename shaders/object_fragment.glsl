// Object view, fragment stage: shading frame, then one lighting mode.
//   MODE_POINT: directional light, f(wi, wo) · max(0, n·L)
//   MODE_FIS:   filtered importance sampling of an HDR lat-long map (Colbert & Křivánek)
//   MODE_MIS:   FIS's BRDF samples plus samples drawn from the map's luminance
//               (shaders/env_sampling.glsl), combined by the power heuristic; with MIS_CONTROL
//               the prefiltered image as a control variate (shaders/mis_control.glsl)
//   MODE_SH:    spherical harmonics (shaders/sh.glsl), unclamped so negative ringing is seen
//   MODE_PREFILTERED: the split sum (shaders/prefiltered.glsl)
// Outputs the sum over this batch's samples (FIS, MIS) so batches add up in a float target.
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
uniform float u_env_fraction;     // MIS: share of the samples drawn from the map (the rest: BRDF)

vec2 env_uv(vec3 d) { return env_uv(d, u_env_rotation); }

// Radiance from world direction d filtered over a sample's solid angle omega_s (Colbert &
// Křivánek): the mip level whose rows span sqrt(omega_s) of θ. Their 0.5 log2(Ωs/Ωp) + 1
// (Ωp the texel's solid angle, ∝ sin θ) made a box twice the sample spacing, taller still
// near the poles; a box that wide gathers light from beyond the local horizon, and
// biased FIS at low counts (docs/mis.md).
// A footprint of a texel or more is filtered as before (bilinear at level 0, trilinear
// above); below a texel the lookup turns to the texel itself, fully at half a texel: a sample
// narrower than a texel sees the map constant per texel, as the quadrature reference and MIS
// do (bilinear there integrates another map: a sub-texel lobe under a one-texel sun stayed
// 10 % off at any count). Turning at one texel instead (texel by texel up to level 1) tripled
// broad lobes' noise under a sun at 1024 samples (Blinn–Phong n = 100: 2.3 → 7.1 %).
vec3 filtered_env(vec3 d, float omega_s) {
    float lod = log2(sqrt(omega_s) * u_env_size.y / PI);
    vec2 uv = env_uv(d);
    if (lod >= 0.0) return textureLod(u_env, uv, min(lod, u_env_max_lod)).rgb;
    ivec2 size = textureSize(u_env, 0);
    vec3 texel = texelFetch(u_env, clamp(ivec2(floor(uv * vec2(size))), ivec2(0), size - 1), 0).rgb;
    return lod <= -1.0 ? texel : mix(texel, textureLod(u_env, uv, 0.0).rgb, lod + 1.0);
}

#ifdef MODE_MIS
// This pixel's Cranley–Patterson shift of the shared sample set (a PCG hash of its position):
// every pixel sampling the same map directions turned MIS's noise at low counts into a
// pattern (all pixels wrong the same way); shifted, each pixel's set is still the stratified
// set, unbiased, and its error independent of its neighbours'.
uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

vec2 pixel_shift() {
    uvec2 p = uvec2(gl_FragCoord.xy);
    uint a = pcg_hash(p.x + pcg_hash(p.y));
    return vec2(a, pcg_hash(a)) * (1.0 / 4294967296.0);
}
#endif

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
    for (int i = u_sample_begin; i < u_sample_end; i++) {
        vec4 s = texelFetch(u_samples, ivec2(i % u_sample_row, i / u_sample_row), 0);
        vec3 wi = material_sample(int(s.z), wo, s.xy);
        if (wi.z <= 0.0) continue;
        float pdf = material_pdf(wi, wo);
        if (!(pdf > 0.0)) continue;
        vec3 radiance = filtered_env(to_world * wi, 1.0 / (u_set_size * pdf));
        color += material_eval(wi, wo) * wi.z * radiance / pdf;
    }
#endif
#ifdef MODE_MIS
    vec2 shift = pixel_shift();
    // Veach's multi-sample estimator: a sample from strategy k adds w_k f L cos / (c_k p_k),
    // c_k the strategy's share of the samples, w_k the power heuristic over c p. The map is
    // read unfiltered, texel by texel (the function its density follows): filtering it over
    // a footprint, as FIS does, blurred lamps beyond the texels the density draws and cost
    // MIS its unbiasedness or its low variance (docs/mis.md).
    // With the control (shaders/mis_control.glsl), each sample adds β P + (f·cos·L − β g) w / p:
    // every sample's term is unbiased alone, so batches and sets of any β add up. Below the
    // horizon g is not 0: the map's samples reach there with weight 1 (the lobes' density taken
    // as 0 below it, as without the control, where those samples add nothing).
#ifdef MIS_CONTROL
    color = u_cv_weight * cv_prepare(to_world, n, wo) * float(u_sample_end - u_sample_begin);
#endif
    for (int i = u_sample_begin; i < u_sample_end; i++) {
        vec4 s = texelFetch(u_samples, ivec2(i % u_sample_row, i / u_sample_row), 0);
        s.xy = fract(s.xy + shift);
        bool from_env = s.z < 0.0;
        vec3 wi, d;
        if (from_env) {
            d = env_sample(s.xy, u_env_rotation);
            wi = vec3(dot(d, t), dot(d, b), dot(d, n));
        } else {
            wi = material_sample(int(s.z), wo, s.xy);
            d = to_world * wi;
        }
#ifdef MIS_CONTROL
        bool above = wi.z > 0.0;
        if (!above && !from_env) continue;
        vec2 uv = env_uv(d, u_env_rotation);  // once: the map's texel, its density and the control's texel
        // below the horizon g is 0 but where a fitted lobe's kernels reach, and in a light's texel
        // whose centre is above it
        if (!above && CV_FITTED == 0 && !cv_light_at(uv)) continue;
        float p_brdf = 0.0;
        if (above) p_brdf = (1.0 - u_env_fraction) * material_pdf(wi, wo);
#else
        if (wi.z <= 0.0) continue;
        float p_brdf = (1.0 - u_env_fraction) * material_pdf(wi, wo);
        vec2 uv = env_uv(d, u_env_rotation);  // once: the map's texel and its density
#endif
        ivec2 texel = env_texel(uv);
        float p_env = u_env_fraction * texelFetch(u_env_table, texel, 0).g;
        float p_own = from_env ? p_env : p_brdf;
        if (!(p_own > 0.0)) continue;
        float ratio = (from_env ? p_brdf : p_env) / p_own;
        float weight = 1.0 / (1.0 + ratio * ratio);  // p_own² / (p_env² + p_brdf²), overflow-free
#ifdef MIS_CONTROL
        vec3 value = vec3(0.0);
        if (above) value = material_eval(wi, wo) * wi.z * texelFetch(u_env, texel, 0).rgb;
        value -= u_cv_weight * cv_control(uv, d, n, to_world, wo);
        color += value * (weight / p_own);
#else
        color += material_eval(wi, wo) * wi.z * texelFetch(u_env, texel, 0).rgb * (weight / p_own);
#endif
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
