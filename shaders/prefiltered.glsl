// Prefiltered environment lighting (the split sum, Karis 2013; brdflab/lighting/split_sum.py
// is its NumPy twin). Per lobe: albedo(cos θo) × (share · irradiance/π + (1 − share) ·
// the stack blended between two roughness layers at the lobe's direction: axis ∘ wo, pulled
// toward n for rough lobes, Lagarde & de Rousiers 2014).
// Irradiance: one fetch; per lobe: two albedo texels, and two stack fetches per lookup if it is
// glossy (one lookup; an anisotropic lobe's: PREF_TAPS around normals spread along its longer axis).
// A rough isotropic lobe (u_pref_fitted) is instead PREF_LOOKUPS lookups per view cosine, fitted
// to its shape at that view (brdflab/lighting/view_mixture.py), blended between two cosines.
// The map's brightest texels are not in the stack: each is a light that the material itself
// is evaluated at (brdflab/lighting/prefilter.bright_lights), as the quadrature does.
uniform sampler2DArray u_pref_stack;   // layer 0: irradiance; then α layers per kernel
uniform sampler2D u_pref_albedo;       // rows k·PREF_PHIS + j: lobe k's directional albedo (RGB) over cos θo at φo = 2π j / PREF_PHIS
uniform float u_pref_albedo_size;      // entries per row, at cos θo = i / (size − 1)
uniform vec4 u_pref_layers[N_LOBES];   // (lower layer, upper layer, weight of the upper, diffuse share)
uniform vec4 u_pref_axis[N_LOBES];     // (axis, w): the lobe looks along normalize(mix(n, normalize(axis ∘ wo), w))
uniform vec3 u_pref_taps[N_LOBES * PREF_TAPS];  // lobe k's lookups: (slope along t, along b, weight); weight 0: none
uniform sampler2D u_pref_mixture;     // RGB32F, PREF_LOOKUPS × (N_LOBES · PREF_COSINES): row k·PREF_COSINES + i holds lobe k's lookups at cos θo = i / (PREF_COSINES − 1): (ψ, stack layer, weight)
uniform float u_pref_fitted[N_LOBES];  // 1: lobe k is drawn by its fitted lookups
uniform float u_pref_rotation;         // the map's turn about +Y, radians
uniform sampler2D u_pref_lights;      // RGB32F, count × 2: row 0 the lights' directions in the map's frame, row 1 their radiance × solid angle
uniform int u_pref_light_count;
uniform float u_pref_blocks;           // 1: the lights are blocks of texels (brdflab/lighting/prefilter.lit_in_blocks)

// light j's direction in the pixel's local frame (the map's turn undone)
vec3 pref_light_local(int j, mat3 to_world) {
    float c = cos(u_pref_rotation), s = sin(u_pref_rotation);
    vec3 m = texelFetch(u_pref_lights, ivec2(j, 0), 0).rgb;
    return vec3(c * m.x - s * m.z, m.y, s * m.x + c * m.z) * to_world;  // env_uv's turn undone, to local
}

// Σ over the lights of f(wi, wo) cos θi × power. Where the lights are blocks of texels
// (u_pref_blocks), the diffuse shares' coefficient `diffuse` is lit by the excess's own irradiance
// (the stack's last layer) and the lights by f less it (brdflab/lighting/split_sum.lights_term)
vec3 prefiltered_lights(mat3 to_world, vec3 n, vec3 wo, vec3 diffuse) {
    vec3 less = u_pref_blocks * diffuse;
    vec3 color = vec3(0.0);
    for (int j = 0; j < u_pref_light_count; j++) {
        vec3 wi = pref_light_local(j, to_world);
        if (wi.z > 0.0) color += (material_eval(wi, wo) - less) * wi.z * texelFetch(u_pref_lights, ivec2(j, 1), 0).rgb;
    }
    float last = float(textureSize(u_pref_stack, 0).z - 1);
    return color + less * texture(u_pref_stack, vec3(env_uv(n, u_pref_rotation), last)).rgb;
}

// lookup j of row `side` (0: the view cosine below wo's, 1: above) of lobe k's fitted mixture: its
// world direction and stack layer, and its weight with the row's share of the blend (`whole`: at
// full weight; ≤ 0: none). Each lookup at ψ from n, away from the view, in the plane of
// incidence, turned by the pixel's view angle less the row's (the lobe moves with the view)
float mixture_lookup(int k, int side, int j, mat3 to_world, vec3 wo, out vec3 d, out float layer, bool whole) {
    float x = clamp(wo.z, 0.0, 1.0) * float(PREF_COSINES - 1);
    int i0 = min(int(x), PREF_COSINES - 2);
    float f = x - float(i0);
    vec3 e = texelFetch(u_pref_mixture, ivec2(j, k * PREF_COSINES + i0 + side), 0).rgb;
    float theta = acos(clamp(wo.z, 0.0, 1.0));
    vec2 toward = length(wo.xy) > 1e-7 ? normalize(wo.xy) : vec2(1.0, 0.0);
    float psi = e.x + theta - acos(max(float(i0 + side) / float(PREF_COSINES - 1), PREF_MIN_COS));
    d = to_world * vec3(-sin(psi) * toward, cos(psi));
    layer = e.y;
    return (whole ? 1.0 : side == 0 ? 1.0 - f : f) * e.z;
}

// a fitted lobe's prefiltered radiance: its lookups of the two view cosines around wo's, blended
vec3 mixture_light(int k, mat3 to_world, vec3 wo) {
    vec3 light = vec3(0.0);
    for (int side = 0; side < 2; side++) {
        for (int j = 0; j < PREF_LOOKUPS; j++) {
            vec3 d;
            float layer;
            float w = mixture_lookup(k, side, j, to_world, wo, d, layer, false);
            if (w > 0.0) light += w * texture(u_pref_stack, vec3(env_uv(d, u_pref_rotation), layer)).rgb;
        }
    }
    return light;
}

// lobe k's directional albedo at wo (RGB), interpolated in full float precision (texture
// filtering weights have ~8 bits)
vec3 pref_albedo(int k, vec3 wo) {
    float x = clamp(wo.z, 0.0, 1.0) * (u_pref_albedo_size - 1.0);
    int i0 = min(int(x), int(u_pref_albedo_size) - 2);
    float f = x - float(i0);
    float y = fract((length(wo.xy) > 1e-7 ? atan(wo.y, wo.x) : 0.0) / (2.0 * PI)) * float(PREF_PHIS);
    int j0 = min(int(y), PREF_PHIS - 1);
    int j1 = (j0 + 1) % PREF_PHIS;
    float g = y - float(j0);
    int r0 = k * PREF_PHIS + j0, r1 = k * PREF_PHIS + j1;
    return mix(mix(texelFetch(u_pref_albedo, ivec2(i0, r0), 0).rgb, texelFetch(u_pref_albedo, ivec2(i0 + 1, r0), 0).rgb, f),
               mix(texelFetch(u_pref_albedo, ivec2(i0, r1), 0).rgb, texelFetch(u_pref_albedo, ivec2(i0 + 1, r1), 0).rgb, f), g);
}

vec3 prefiltered_shade(mat3 to_world, vec3 n, vec3 wo) {
    vec3 irradiance = texture(u_pref_stack, vec3(env_uv(n, u_pref_rotation), 0.0)).rgb;
    vec3 color = vec3(0.0), diffuse = vec3(0.0);
    for (int k = 0; k < N_LOBES; k++) {
        vec4 layers = u_pref_layers[k];
        vec3 scale = u_lobe_scale[k] * pref_albedo(k, wo);
        diffuse += scale * layers.w / PI;
        vec3 light = layers.w * irradiance / PI;
        if (u_pref_fitted[k] > 0.5) light += mixture_light(k, to_world, wo);
        for (int j = 0; j < PREF_TAPS && layers.w < 1.0 && u_pref_fitted[k] < 0.5; j++) {
            vec3 tap = u_pref_taps[k * PREF_TAPS + j];
            if (tap.z <= 0.0) break;
            // the lobe's axis ∘ wo; a tilted tap (an anisotropic lobe's): wo mirrored about its normal
            vec3 normal = normalize(vec3(-tap.xy, 1.0));
            vec3 axis = tap.xy == vec2(0.0) ? stable_axis(u_pref_axis[k].xyz * wo)
                                             : stable_axis(reflect_about(wo, normal));
            vec3 d = stable_axis(mix(normal, axis, u_pref_axis[k].w));
            vec2 uv = env_uv(to_world * d, u_pref_rotation);
            vec3 glossy = mix(texture(u_pref_stack, vec3(uv, layers.x)).rgb,
                              texture(u_pref_stack, vec3(uv, layers.y)).rgb, layers.z);
            light += (1.0 - layers.w) * tap.z * glossy;
        }
        color += scale * light;
    }
    return color + prefiltered_lights(to_world, n, wo, diffuse);
}
