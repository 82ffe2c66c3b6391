// Normalised reciprocal Phong: (n+2)/(2π) cos^n α.  p = [Exponent]
float brdf_Phong(vec3 wi, vec3 wo, float p[NP]) {
    return (p[0] + 2.0) / (2.0 * PI) * safe_pow(max(dot(mirror_z(wi), wo), 0.0), p[0]);
}
vec3 sample_Phong(vec3 wo, vec2 u, float p[NP]) { return cosine_power_around(mirror_z(wo), p[0], u); }
float pdf_Phong(vec3 wi, vec3 wo, float p[NP]) { return cosine_power_pdf(wi, mirror_z(wo), p[0]); }
