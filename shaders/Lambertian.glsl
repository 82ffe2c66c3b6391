// Lambertian: value 1 (a Linear scaling factor is ρd/π).
float brdf_Lambertian(vec3 wi, vec3 wo, float p[NP]) { return 1.0; }
vec3 sample_Lambertian(vec3 wo, vec2 u, float p[NP]) { return cosine_hemisphere(u); }
float pdf_Lambertian(vec3 wi, vec3 wo, float p[NP]) { return cosine_hemisphere_pdf(wi); }
