// Disney's principled BRDF, reflection only, as Mitsuba 3's `principled` (brdflab/models/principled.py).
// p = [base r, g, b, metallic, subsurface, specular, specular_tint, roughness, anisotropic,
//      sheen, sheen_tint, clearcoat, clearcoat_gloss]
const vec3 PRINCIPLED_TINT_LUM = vec3(0.212671, 0.715160, 0.072169);
float principled_w(float c) { float m = clamp(1.0 - c, 0.0, 1.0); return (m * m) * (m * m) * m; }
vec2 principled_alphas(float p[NP]) {
    float r2 = p[7] * p[7];
    float aspect = sqrt(1.0 - 0.9 * p[8]);
    return vec2(max(0.001, r2 / aspect), max(0.001, r2 * aspect));
}
float principled_d(vec3 h, vec2 a) {
    if (h.z <= 0.0) return 0.0;
    float e = (h.x / a.x) * (h.x / a.x) + (h.y / a.y) * (h.y / a.y) + h.z * h.z;
    return 1.0 / max(PI * a.x * a.y * e * e, TINY);
}
float principled_g1(vec3 v, vec2 a) {
    float t2 = ((a.x * v.x) * (a.x * v.x) + (a.y * v.y) * (a.y * v.y)) / max(v.z * v.z, TINY);
    return 2.0 / (1.0 + sqrt(1.0 + t2));
}
float principled_fresnel(float ci, float eta) {
    ci = clamp(ci, 0.0, 1.0);
    float st2 = (1.0 - ci * ci) / (eta * eta);
    if (st2 >= 1.0) return 1.0;
    float ct = sqrt(1.0 - st2);
    float rs = (ci - eta * ct) / max(ci + eta * ct, TINY);
    float rp = (eta * ci - ct) / max(eta * ci + ct, TINY);
    return 0.5 * (rs * rs + rp * rp);
}
float principled_cc_alpha(float gloss) { return mix(0.1, 0.001, gloss); }
float principled_gtr1(vec3 h, float a) {
    if (h.z <= 0.0) return 0.0;
    float a2 = a * a;
    return (a2 - 1.0) / (PI * log(a2) * (1.0 + (a2 - 1.0) * h.z * h.z));
}
vec3 principled_tint(vec3 c) {
    float lum = dot(c, PRINCIPLED_TINT_LUM);
    return lum > 0.0 ? c / lum : vec3(1.0);
}
vec3 brdf_Principled_rgb(vec3 wi, vec3 wo, float p[NP]) {
    vec3 colour = vec3(p[0], p[1], p[2]);
    float metallic = p[3], st = p[6];
    vec3 h = normalize(wi + wo);
    float cos_d = dot(wi, h);
    float w = principled_w(cos_d);
    vec2 a = principled_alphas(p);
    float dg = principled_d(h, a) * principled_g1(wi, a) * principled_g1(wo, a) / (4.0 * wi.z * wo.z);
    float eta = 2.0 / (1.0 - sqrt(0.08 * p[5])) - 1.0;
    float r0 = ((eta - 1.0) / (eta + 1.0)) * ((eta - 1.0) / (eta + 1.0));
    vec3 tinted = principled_tint(colour) * r0;
    vec3 fresnel = (1.0 - metallic) * (1.0 - st) * principled_fresnel(cos_d, eta)
        + metallic * (colour + (1.0 - colour) * w) + (1.0 - metallic) * st * (tinted + (1.0 - tinted) * w);
    vec3 value = fresnel * dg;
    float g_cc = principled_g1(wi, vec2(0.25)) * principled_g1(wo, vec2(0.25));
    value += vec3(0.25 * p[11] * (0.04 + 0.96 * w) * principled_gtr1(h, principled_cc_alpha(p[12])) * g_cc);
    float fo = principled_w(wo.z), fi = principled_w(wi.z);
    float rr = 2.0 * p[7] * cos_d * cos_d;
    float lambert = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
    float retro = rr * (fo + fi + fo * fi * (rr - 1.0));
    float fss90 = 0.5 * rr;
    float fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi);
    float flat_ = 1.25 * (fss * (1.0 / (wi.z + wo.z) - 0.5) + 0.5);
    value += (1.0 - metallic) * colour * (mix(lambert + retro, flat_, p[4]) / PI);
    vec3 sheen_colour = mix(vec3(1.0), principled_tint(colour), p[10]);
    value += p[9] * (1.0 - metallic) * sheen_colour * w;
    return value;
}
float brdf_Principled(vec3 wi, vec3 wo, float p[NP]) {
    return dot(brdf_Principled_rgb(wi, wo, p), vec3(0.2126, 0.7152, 0.0722));
}
// Mitsuba's sampling rates: diffuse 1 − metallic, clear coat clearcoat / 4, main lobe 1
vec3 principled_shares(float p[NP]) {
    vec3 s = vec3(1.0 - p[3], 0.25 * p[11], 1.0);
    return s / (s.x + s.y + s.z);
}
vec3 principled_ggx_half(vec2 a, vec2 u) {
    float phase = 2.0 * PI * u.y;
    float phi = atan(a.y * sin(phase), a.x * cos(phase));
    float c = cos(phi), s = sin(phi);
    float a2 = 1.0 / (c * c / (a.x * a.x) + s * s / (a.y * a.y));
    float tan2 = a2 * u.x / max(1.0 - u.x, TINY);
    float ct = 1.0 / sqrt(1.0 + tan2);
    float st = sqrt(max(0.0, 1.0 - ct * ct));
    return vec3(st * c, st * s, ct);
}
vec3 principled_gtr1_half(float a, vec2 u) {
    float a2 = a * a;
    float ct = sqrt(clamp((1.0 - pow(a2, 1.0 - u.x)) / (1.0 - a2), 0.0, 1.0));
    float st = sqrt(max(0.0, 1.0 - ct * ct));
    float phi = 2.0 * PI * u.y;
    return vec3(st * cos(phi), st * sin(phi), ct);
}
vec3 sample_Principled(vec3 wo, vec2 u, float p[NP]) {
    vec3 s = principled_shares(p);
    if (u.x < s.x) return cosine_hemisphere(vec2(min(u.x / s.x, 0.99999994), u.y));
    if (u.x < s.x + s.y) return reflect_about(wo, principled_gtr1_half(principled_cc_alpha(p[12]), vec2(min((u.x - s.x) / s.y, 0.99999994), u.y)));
    return reflect_about(wo, principled_ggx_half(principled_alphas(p), vec2(min((u.x - s.x - s.y) / s.z, 0.99999994), u.y)));
}
float pdf_Principled(vec3 wi, vec3 wo, float p[NP]) {
    vec3 s = principled_shares(p);
    vec3 h = upper_half(wi, wo);
    float cc = half_pdf_from(principled_gtr1(h, principled_cc_alpha(p[12])) * h.z, wi, wo);
    float main = half_pdf_from(principled_d(h, principled_alphas(p)) * h.z, wi, wo);
    return s.x * cosine_hemisphere_pdf(wi) + s.y * cc + s.z * main;
}
