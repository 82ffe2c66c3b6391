// Ward lobe with Dür's normalisation.  p = [ax, ay]
float brdf_WardDuer(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float e = (h.x * h.x / (p[0] * p[0]) + h.y * h.y / (p[1] * p[1])) / (h.z * h.z);
    return exp(-e) / (4.0 * PI * p[0] * p[1] * wi.z * wo.z);
}
vec3 sample_WardDuer(vec3 wo, vec2 u, float p[NP]) { return reflect_about(wo, beckmann_half(p[0], p[1], u)); }
float pdf_WardDuer(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(beckmann_d(h, p[0], p[1]) * h.z, wi, wo);
}
