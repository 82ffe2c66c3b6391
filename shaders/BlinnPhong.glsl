// Normalised Blinn–Phong: (n+2)/(2π) cos^n θh.  p = [Exponent]
float brdf_BlinnPhong(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    return (p[0] + 2.0) / (2.0 * PI) * safe_pow(max(h.z, 0.0), p[0]);
}
vec3 sample_BlinnPhong(vec3 wo, vec2 u, float p[NP]) {
    return reflect_about(wo, cosine_power_around(vec3(0.0, 0.0, 1.0), p[0], u));
}
float pdf_BlinnPhong(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    return half_pdf_from(cosine_power_pdf(h, vec3(0.0, 0.0, 1.0), p[0]), wi, wo);
}
