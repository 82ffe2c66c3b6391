// Anisotropic Lafortune lobe.  p = [Cx, Cy, Cz, Exponent]
float brdf_LafortuneAniso(vec3 wi, vec3 wo, float p[NP]) {
    float s = p[0] * wi.x * wo.x + p[1] * wi.y * wo.y + p[2] * wi.z * wo.z;
    float cmax = max(max(max(abs(p[0]), abs(p[1])), abs(p[2])), TINY);
    return (p[3] + 2.0) / (2.0 * PI) * safe_pow(max(s, 0.0) / cmax, p[3]);
}
vec3 sample_LafortuneAniso(vec3 wo, vec2 u, float p[NP]) {
    return cosine_power_around(stable_axis(vec3(p[0], p[1], p[2]) * wo), p[3], u);
}
float pdf_LafortuneAniso(vec3 wi, vec3 wo, float p[NP]) {
    return cosine_power_pdf(wi, stable_axis(vec3(p[0], p[1], p[2]) * wo), p[3]);
}
