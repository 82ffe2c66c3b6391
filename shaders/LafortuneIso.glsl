// Isotropic Lafortune lobe, normalised as in BRDFLab.  p = [Cxy, Cz, Exponent]
float brdf_LafortuneIso(vec3 wi, vec3 wo, float p[NP]) {
    float s = p[0] * (wi.x * wo.x + wi.y * wo.y) + p[1] * wi.z * wo.z;
    float cmax = max(max(abs(p[0]), abs(p[1])), TINY);
    return (p[2] + 2.0) / (2.0 * PI) * safe_pow(max(s, 0.0) / cmax, p[2]);
}
vec3 sample_LafortuneIso(vec3 wo, vec2 u, float p[NP]) {
    return cosine_power_around(stable_axis(vec3(p[0] * wo.x, p[0] * wo.y, p[1] * wo.z)), p[2], u);
}
float pdf_LafortuneIso(vec3 wi, vec3 wo, float p[NP]) {
    return cosine_power_pdf(wi, stable_axis(vec3(p[0] * wo.x, p[0] * wo.y, p[1] * wo.z)), p[2]);
}
