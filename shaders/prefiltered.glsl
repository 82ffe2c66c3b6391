// Prefiltered environment lighting (the split sum, Karis 2013; brdflab/lighting/split_sum.py
// is its NumPy twin). Per lobe: albedo(cos θo) × (share · irradiance/π + (1 − share) ·
// the stack blended between two roughness layers at the lobe's direction: axis ∘ wo, pulled
// toward n for rough lobes, Lagarde & de Rousiers 2014).
// Irradiance: one fetch; per lobe: two albedo texels, and two stack fetches if it is glossy.
uniform sampler2DArray u_pref_stack;   // layer 0: irradiance; then α layers per kernel
uniform sampler2D u_pref_albedo;       // row k: lobe k's directional albedo (RGB) over cos θo
uniform float u_pref_albedo_size;      // entries per row, at cos θo = i / (size − 1)
uniform vec4 u_pref_layers[N_LOBES];   // (lower layer, upper layer, weight of the upper, diffuse share)
uniform vec4 u_pref_axis[N_LOBES];     // (axis, w): the lobe looks along normalize(mix(n, normalize(axis ∘ wo), w))
uniform float u_pref_rotation;         // the map's turn about +Y, radians

vec3 prefiltered_shade(mat3 to_world, vec3 n, vec3 wo) {
    vec3 irradiance = texture(u_pref_stack, vec3(env_uv(n, u_pref_rotation), 0.0)).rgb;
    // the albedo interpolated in full float precision (texture filtering weights have ~8 bits)
    float x = clamp(wo.z, 0.0, 1.0) * (u_pref_albedo_size - 1.0);
    int i0 = min(int(x), int(u_pref_albedo_size) - 2);
    float f = x - float(i0);
    vec3 color = vec3(0.0);
    for (int k = 0; k < N_LOBES; k++) {
        vec4 layers = u_pref_layers[k];
        vec3 albedo = mix(texelFetch(u_pref_albedo, ivec2(i0, k), 0).rgb, texelFetch(u_pref_albedo, ivec2(i0 + 1, k), 0).rgb, f);
        vec3 light = layers.w * irradiance / PI;
        if (layers.w < 1.0) {
            vec3 axis = stable_axis(u_pref_axis[k].xyz * wo);
            vec3 d = stable_axis(mix(vec3(0.0, 0.0, 1.0), axis, u_pref_axis[k].w));
            vec2 uv = env_uv(to_world * d, u_pref_rotation);
            vec3 glossy = mix(texture(u_pref_stack, vec3(uv, layers.x)).rgb,
                              texture(u_pref_stack, vec3(uv, layers.y)).rgb, layers.z);
            light += (1.0 - layers.w) * glossy;
        }
        color += u_lobe_scale[k] * albedo * light;
    }
    return color;
}
