// Ward 1992.  p = [ax, ay]
float ward_gaussian(vec3 wi, vec3 wo, float ax, float ay) {
    vec3 h = half_vec(wi, wo);
    float e = (h.x * h.x / (ax * ax) + h.y * h.y / (ay * ay)) / (h.z * h.z);
    return exp(-e) / (4.0 * PI * ax * ay);
}
float brdf_Ward(vec3 wi, vec3 wo, float p[NP]) { return ward_gaussian(wi, wo, p[0], p[1]) / sqrt(wi.z * wo.z); }
vec3 sample_Ward(vec3 wo, vec2 u, float p[NP]) { return reflect_about(wo, beckmann_half(p[0], p[1], u)); }
float pdf_Ward(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(beckmann_d(h, p[0], p[1]) * h.z, wi, wo);
}
