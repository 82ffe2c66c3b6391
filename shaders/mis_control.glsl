// MIS with the prefiltered image as a control variate (brdflab/lighting/control_variate.py is
// its NumPy twin, the MIS twin brdflab/lighting/auto_twins.mis_parts): a pixel is
// β P + MIS[f·cos·L − β g], g a function of the direction whose integral is P — the irradiance
// kernel × the diffuse shares, each lookup of the fitted lobes among the first four at the nearer
// view cosine × its layer's kernel (over its integral), all × the stack's dimmed map texel by texel,
// plus, in a light's texel, f·cos at the light's direction × the texel's excess (with the diffuse shares
// taken apart where the lights are blocks). Needs shaders/prefiltered.glsl.
uniform float u_cv_weight;              // β, fixed per material and map before any sample
uniform vec3 u_cv_layer[PREF_LAYERS];   // per stack layer: (kernel family: 0 cosine, 1 Beckmann, 2 GGX, 3 Phong; α; 1 / ∫K, 0: no kernel)
uniform sampler2D u_cv_excess;          // RGBA32F at the stack's texels: a light's excess radiance, its index (−1: none)

// this pixel's g: the irradiance kernel's coefficient, and the fitted lobes' lookups: lobe k's in
// slots CV_SLOT[k]·PREF_LOOKUPS + j (CV_SLOT[k] < 0: not in g), its kernel family CV_FAMILIES[slot]
// (1: Beckmann, 2: GGX). A program per set of fitted lobes and families, so that a sample draws no
// kernel it does not need: llvmpipe runs both sides of a branch under masks, and an empty loop of
// kernels of every family cost a Lambertian's frame as much as its sampling.
const int cv_slot[N_LOBES] = CV_SLOTS;
const int cv_family[] = CV_FAMILIES;
vec3 cv_diffuse;
vec3 cv_direction[CV_LOOKUPS];
vec2 cv_shape[CV_LOOKUPS];  // (α², 1 / ∫K); 0: no lookup
vec3 cv_coefficient[CV_LOOKUPS];

// a fitted lookup's kernel over its integral at cosine c to its direction (prefilter.specular_kernel:
// common.glsl's beckmann_d and ggx_d of an isotropic half vector, written in cos²θh to spare the
// sample loop their square roots)
float cv_kernel(int family, vec2 shape, float c) {
    float h2 = 0.5 * (1.0 + c);  // cos²θh
    float d = h2 * (shape.x - 1.0) + 1.0;
    float k = family == 1 ? exp(-(1.0 - h2) / (h2 * shape.x)) / (PI * shape.x * h2 * h2) : shape.x / (PI * d * d);
    return c > 0.0 ? k * c * shape.y : 0.0;
}

// this pixel's control: fills its lookups, returns its integral P
vec3 cv_prepare(mat3 to_world, vec3 n, vec3 wo) {
    vec3 exact = vec3(0.0);
    cv_diffuse = vec3(0.0);
    for (int m = 0; m < CV_FITTED * PREF_LOOKUPS; m++) {
        cv_shape[m] = vec2(1.0, 0.0);
        cv_coefficient[m] = vec3(0.0);
    }
    float x = clamp(wo.z, 0.0, 1.0) * float(PREF_COSINES - 1);
    int side = x - float(min(int(x), PREF_COSINES - 2)) >= 0.5 ? 1 : 0;  // the nearer view cosine's row, at full weight
    for (int k = 0; k < N_LOBES; k++) {
        vec3 scale = u_lobe_scale[k] * pref_albedo(k, wo);
        cv_diffuse += scale * u_pref_layers[k].w / PI;
        if (cv_slot[k] < 0) continue;
        for (int j = 0; j < PREF_LOOKUPS; j++) {
            vec3 d;
            float layer;
            float w = mixture_lookup(k, side, j, to_world, wo, d, layer, true);
            if (!(w > 0.0)) continue;
            int m = cv_slot[k] * PREF_LOOKUPS + j;
            cv_direction[m] = d;
            vec3 kernel = u_cv_layer[int(layer + 0.5)];  // (family, α, 1 / ∫K)
            cv_shape[m] = vec2(kernel.y * kernel.y, kernel.z);
            cv_coefficient[m] = scale * w;
            exact += scale * w * texture(u_pref_stack, vec3(env_uv(d, u_pref_rotation), layer)).rgb;
        }
    }
    return exact + prefiltered_lights(to_world, n, wo, cv_diffuse)
           + cv_diffuse * texture(u_pref_stack, vec3(env_uv(n, u_pref_rotation), 0.0)).rgb;
}

// whether map coordinates uv fall in a light's texel
bool cv_light_at(vec2 uv) { return texelFetch(u_cv_excess, latlong_texel(uv, textureSize(u_cv_excess, 0)), 0).a >= 0.0; }

// g at world direction d, at map coordinates uv (env_uv)
vec3 cv_control(vec2 uv, vec3 d, vec3 n, mat3 to_world, vec3 wo) {
    ivec2 texel = latlong_texel(uv, textureSize(u_cv_excess, 0));
    vec3 dimmed = texelFetch(u_pref_stack, ivec3(texel, 1), 0).rgb;  // layer 1 (Beckmann, α = 0): the dimmed map
    vec3 weight = cv_diffuse * max(dot(n, d), 0.0);
    for (int m = 0; m < CV_FITTED * PREF_LOOKUPS; m++)
        weight += cv_coefficient[m] * cv_kernel(cv_family[m / PREF_LOOKUPS], cv_shape[m], dot(d, cv_direction[m]));
    vec3 g = weight * dimmed;
    vec4 excess = texelFetch(u_cv_excess, texel, 0);
    if (excess.a >= 0.0) {  // where the lights are blocks, the diffuse shares × the excess texel by texel
        vec3 wi = pref_light_local(int(excess.a + 0.5), to_world);
        if (wi.z > 0.0) g += (material_eval(wi, wo) - u_pref_blocks * cv_diffuse) * wi.z * excess.rgb;
        g += u_pref_blocks * cv_diffuse * max(dot(n, d), 0.0) * excess.rgb;
    }
    return g;
}
