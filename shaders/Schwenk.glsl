// The survey's own model, specular term (Schwenk 2011 §4).  p = [smoothness, metalness, tint]
float schwenk_exponent(float s) { return 2.0 / (1.0 + 1.0 / 255.0 - s); }
float brdf_Schwenk(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float woh = dot(wo, h);
    float f0 = 1.0 - p[1] + p[1] * p[2];
    return p[0] * p[0] / woh * schlick(f0, woh) * safe_pow(max(h.z, 0.0), schwenk_exponent(p[0]));
}
vec3 sample_Schwenk(vec3 wo, vec2 u, float p[NP]) {
    return reflect_about(wo, cosine_power_around(vec3(0.0, 0.0, 1.0), schwenk_exponent(p[0]), u));
}
float pdf_Schwenk(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(cosine_power_pdf(h, vec3(0.0, 0.0, 1.0), schwenk_exponent(p[0])), wi, wo);
}
