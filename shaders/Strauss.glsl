// Strauss 1990 (Schwenk 2011 §3.9).  p = [smoothness, metalness, transparency, color]
// stable forms of Strauss's F and G (1/A² − 1/B² = (B−A)(B+A)/(AB)²), as in strauss.py
float strauss_fresnel(float theta) {
    float x = theta / (0.5 * PI);
    const float kf = 1.12;
    float a = kf * (x - kf), b = kf * (1.0 - kf);
    return x * (2.0 * kf - x) / (a * a) / ((2.0 * kf - 1.0) / (b * b));
}
float strauss_shadow(float theta) {
    float x = theta / (0.5 * PI);
    const float kg = 1.01;
    float a = (1.0 - kg) * (x - kg), b = kg * (1.0 - kg);
    return (1.0 - x) * (1.0 + x - 2.0 * kg) / (a * a) / ((1.0 - 2.0 * kg) / (b * b));
}
float brdf_Strauss(vec3 wi, vec3 wo, float p[NP]) {
    float s = p[0], m = p[1], t = p[2], c = p[3];
    float ti = precise_acos(wi.z), to = precise_acos(wo.z);
    float rd = (1.0 - s * s * s) * (1.0 - t);
    float d = 1.0 - m * s;
    float rn = (1.0 - t) - rd;
    float fi = strauss_fresnel(ti);
    float j = fi * strauss_shadow(ti) * strauss_shadow(to);
    float rj = min(1.0, rn + (rn + 0.1) * j);
    float rs = rj * safe_pow(max(dot(mirror_z(wi), wo), 0.0), 3.0 / (1.0 - s));
    float cs = 1.0 + m * (1.0 - fi) * (c - 1.0);
    return rd * d * c / PI + rs * cs / max(wi.z, TINY);
}
