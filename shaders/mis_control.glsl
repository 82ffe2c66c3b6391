// MIS with the prefiltered image as a control variate (brdflab/lighting/control_variate.py is
// its NumPy twin, the MIS twin brdflab/lighting/auto_twins.mis_parts): a pixel is
// β P + MIS[f·cos·L − β g], g a function of the direction whose integral is P — the irradiance
// kernel × the diffuse shares, each lookup of the first CV_FITTED fitted lobes × its layer's
// kernel (normalised as the stack normalises it), all × the stack's dimmed map texel by texel,
// plus a light texel's f·cos at its centre × its excess. Needs shaders/prefiltered.glsl.
uniform float u_cv_weight;              // β, fixed per material and map before any sample
uniform vec3 u_cv_layer[PREF_LAYERS];   // per stack layer: (kernel family: 0 cosine, 1 Beckmann, 2 GGX, 3 Phong; α; 1 / ∫K, 0: no kernel)
uniform sampler2D u_cv_excess;          // RGBA32F at the stack's texels: a light's excess radiance, its index (−1: none)

vec3 cv_diffuse;                        // this pixel's coefficient of the irradiance kernel max(0, n·ω)
vec3 cv_direction[CV_LOOKUPS];          // this pixel's fitted lookups: world direction, layer, coefficient
int cv_layer_of[CV_LOOKUPS];
vec3 cv_coefficient[CV_LOOKUPS];
int cv_count;

// a stack layer's kernel at cosine c to its centre, over its integral (prefilter.specular_kernel)
float cv_kernel(int layer, float c) {
    vec3 k = u_cv_layer[layer];
    if (c <= 0.0 || k.z <= 0.0) return 0.0;
    if (k.x < 0.5) return c * k.z;
    float a2 = k.y * k.y;
    float h2 = 0.5 * (1.0 + c);  // cos²θh
    if (k.x < 1.5) return exp(-(1.0 - h2) / (h2 * a2)) / (PI * a2 * h2 * h2) * c * k.z;
    if (k.x < 2.5) {
        float d = h2 * (a2 - 1.0) + 1.0;
        return a2 / (PI * d * d) * c * k.z;
    }
    return pow(c, (2.0 / a2 - 2.0) / 4.0 + 1.0) * k.z;
}

// this pixel's control: fills its lookups, returns its integral P
vec3 cv_prepare(mat3 to_world, vec3 n, vec3 wo) {
    vec3 exact = prefiltered_lights(to_world, wo);
    cv_diffuse = vec3(0.0);
    cv_count = 0;
    int fitted = 0;
    for (int k = 0; k < N_LOBES; k++) {
        vec3 scale = u_lobe_scale[k] * pref_albedo(k, wo);
        cv_diffuse += scale * u_pref_layers[k].w / PI;
        if (u_pref_fitted[k] < 0.5 || fitted == CV_FITTED) continue;
        fitted++;
        for (int side = 0; side < 2; side++) {
            for (int j = 0; j < PREF_LOOKUPS; j++) {
                vec3 d;
                float layer;
                float w = mixture_lookup(k, side, j, to_world, wo, d, layer);
                if (!(w > 0.0)) continue;
                cv_direction[cv_count] = d;
                cv_layer_of[cv_count] = int(layer + 0.5);
                cv_coefficient[cv_count] = scale * w;
                exact += scale * w * texture(u_pref_stack, vec3(env_uv(d, u_pref_rotation), layer)).rgb;
                cv_count++;
            }
        }
    }
    return exact + cv_diffuse * texture(u_pref_stack, vec3(env_uv(n, u_pref_rotation), 0.0)).rgb;
}

// g at world direction d
vec3 cv_control(vec3 d, vec3 n, mat3 to_world, vec3 wo) {
    ivec2 size = textureSize(u_cv_excess, 0);
    ivec2 texel = clamp(ivec2(floor(env_uv(d, u_pref_rotation) * vec2(size))), ivec2(0), size - 1);
    vec3 dimmed = texelFetch(u_pref_stack, ivec3(texel, 1), 0).rgb;  // layer 1 (Beckmann, α = 0): the dimmed map
    vec3 weight = cv_diffuse * max(dot(n, d), 0.0);
    for (int m = 0; m < cv_count; m++) weight += cv_coefficient[m] * cv_kernel(cv_layer_of[m], dot(d, cv_direction[m]));
    vec3 g = weight * dimmed;
    vec4 excess = texelFetch(u_cv_excess, texel, 0);
    if (excess.a >= 0.0) {
        vec3 wi = pref_light_local(int(excess.a + 0.5), to_world);
        if (wi.z > 0.0) g += material_eval(wi, wo) * wi.z * excess.rgb;
    }
    return g;
}
