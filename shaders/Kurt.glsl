// Kurt, Szirmay-Kalos & Křivánek 2010, eq. 10; sampling eqs. 16–20.  p = [mx, my, F0, alpha]
float brdf_Kurt(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float woh = dot(wo, h);
    return schlick(p[2], woh) * beckmann_d(h, p[0], p[1]) / (4.0 * woh * wi.z * pow(wo.z, p[3]));
}
vec3 sample_Kurt(vec3 wo, vec2 u, float p[NP]) { return reflect_about(wo, beckmann_half(p[0], p[1], u)); }
float pdf_Kurt(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(beckmann_d(h, p[0], p[1]) * h.z, wi, wo);
}
