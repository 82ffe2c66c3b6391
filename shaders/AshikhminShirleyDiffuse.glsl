// Ashikhmin–Shirley coupled diffuse term (scale by ρd/π).  p = [Rs]
float brdf_AshikhminShirleyDiffuse(vec3 wi, vec3 wo, float p[NP]) {
    // 1 − (1 − x)^5 expanded, which keeps float32 precision at grazing angles
    float x = 0.5 * wi.z, y = 0.5 * wo.z;
    float a = x * (5.0 - x * (10.0 - x * (10.0 - x * (5.0 - x))));
    float b = y * (5.0 - y * (10.0 - y * (10.0 - y * (5.0 - y))));
    return 28.0 / 23.0 * (1.0 - p[0]) * a * b;
}
vec3 sample_AshikhminShirleyDiffuse(vec3 wo, vec2 u, float p[NP]) { return cosine_hemisphere(u); }
float pdf_AshikhminShirleyDiffuse(vec3 wi, vec3 wo, float p[NP]) { return cosine_hemisphere_pdf(wi); }
