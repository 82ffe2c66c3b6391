// Ashikhmin–Shirley anisotropic specular lobe.  p = [nu, nv, F0]
float as_exponent(vec3 h, float nu, float nv) {
    float s2 = h.x * h.x + h.y * h.y;
    return s2 > 1e-14 ? (nu * h.x * h.x + nv * h.y * h.y) / s2 : 0.5 * (nu + nv);
}
float brdf_AshikhminShirley(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = half_vec(wi, wo);
    float wih = dot(wi, h);
    float norm = sqrt((p[0] + 1.0) * (p[1] + 1.0)) / (8.0 * PI);
    return norm * safe_pow(max(h.z, 0.0), as_exponent(h, p[0], p[1])) * schlick(p[2], wih) / (wih * max(wi.z, wo.z));
}
vec3 sample_AshikhminShirley(vec3 wo, vec2 u, float p[NP]) {
    float phase = 2.0 * PI * u.x;
    float phi = atan(sqrt(p[0] + 1.0) * sin(phase), sqrt(p[1] + 1.0) * cos(phase));
    float c = cos(phi), s = sin(phi);
    float ct = pow(max(1.0 - u.y, 1e-30), 1.0 / (p[0] * c * c + p[1] * s * s + 1.0));
    float st = sqrt(max(0.0, 1.0 - ct * ct));
    return reflect_about(wo, vec3(st * c, st * s, ct));
}
float pdf_AshikhminShirley(vec3 wi, vec3 wo, float p[NP]) {
    vec3 h = upper_half(wi, wo);
    float pdf_h = sqrt((p[0] + 1.0) * (p[1] + 1.0)) / (2.0 * PI) * safe_pow(max(h.z, 0.0), as_exponent(h, p[0], p[1]));
    return half_pdf_from(pdf_h, wi, wo);
}
