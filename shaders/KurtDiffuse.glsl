// Kurt et al. eq. 13: Fresnel-coupled diffuse term 1 − F(wo·h) (scale by kd/π).  p = [F0]
float brdf_KurtDiffuse(vec3 wi, vec3 wo, float p[NP]) { return 1.0 - schlick(p[0], dot(wo, half_vec(wi, wo))); }
vec3 sample_KurtDiffuse(vec3 wo, vec2 u, float p[NP]) { return cosine_hemisphere(u); }
float pdf_KurtDiffuse(vec3 wi, vec3 wo, float p[NP]) { return cosine_hemisphere_pdf(wi); }
