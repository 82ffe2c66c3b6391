// Helpers shared by every lobe model (the GLSL twins of brdflab/vec.py and sampling.py).
// Directions are in the local frame: z = normal. Parameters come as float p[NP] in the
// order the model declares them, then zeros. NP is defined by the program that includes this
// (brdflab.render.glsl: the most parameters a lobe of the material has, at least 8).
const float PI = 3.14159265358979;
const float TINY = 1e-12;

float schlick(float f0, float c) {
    float m = clamp(1.0 - c, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (1.0 - f0) * m2 * m2 * m;
}

float safe_pow(float x, float n) { return x <= 0.0 ? (n == 0.0 ? 1.0 : 0.0) : exp(n * log(x)); }

vec3 half_vec(vec3 wi, vec3 wo) { return normalize(wi + wo); }

vec3 mirror_z(vec3 w) { return vec3(-w.x, -w.y, w.z); }

void frame_around(vec3 a, out vec3 t, out vec3 b) {
    float s = a.z >= 0.0 ? 1.0 : -1.0;
    float k = -1.0 / (s + a.z);
    float q = a.x * a.y * k;
    t = vec3(1.0 + s * a.x * a.x * k, s * q, -s * a.x);
    b = vec3(q, s + a.y * a.y * k, -a.y);
}

vec3 cosine_hemisphere(vec2 u) {
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u.x)));
}

float cosine_hemisphere_pdf(vec3 wi) { return max(wi.z, 0.0) / PI; }

vec3 cosine_power_around(vec3 axis, float n, vec2 u) {
    float c = pow(max(u.x, 1e-30), 1.0 / (n + 1.0));
    float s = sqrt(max(0.0, 1.0 - c * c));
    float phi = 2.0 * PI * u.y;
    vec3 t, b;
    frame_around(axis, t, b);
    return s * cos(phi) * t + s * sin(phi) * b + c * axis;
}

float cosine_power_pdf(vec3 w, vec3 axis, float n) { return (n + 1.0) / (2.0 * PI) * safe_pow(max(dot(w, axis), 0.0), n); }

vec3 stable_axis(vec3 v) { float l = length(v); return l > 1e-9 ? v / l : vec3(0.0, 0.0, 1.0); }

vec3 reflect_about(vec3 wo, vec3 h) { return 2.0 * dot(wo, h) * h - wo; }

// half vector of (wi, wo) flipped into the upper hemisphere, as in sampling.upper_half_vector
vec3 upper_half(vec3 wi, vec3 wo) { vec3 h = normalize(wi + wo); return h.z < 0.0 ? -h : h; }

float beckmann_d(vec3 h, float mx, float my) {
    if (h.z <= 0.0) return 0.0;
    float hz2 = h.z * h.z;
    float e = (h.x * h.x / (mx * mx) + h.y * h.y / (my * my)) / hz2;
    return exp(-e) / (PI * mx * my * hz2 * hz2);
}

vec3 beckmann_half(float mx, float my, vec2 u) {
    float phase = 2.0 * PI * u.y;
    float phi = atan(my * sin(phase), mx * cos(phase));
    float c = cos(phi), s = sin(phi);
    float tan2 = -log(max(1.0 - u.x, TINY)) / (c * c / (mx * mx) + s * s / (my * my));
    float ct = 1.0 / sqrt(1.0 + tan2);
    float st = sqrt(max(0.0, 1.0 - ct * ct));
    return vec3(st * c, st * s, ct);
}

float ggx_d(vec3 h, float a) {
    if (h.z <= 0.0) return 0.0;
    float a2 = a * a, hz2 = h.z * h.z;
    float d = PI * (hz2 * (a2 - 1.0) + 1.0) * (hz2 * (a2 - 1.0) + 1.0);
    return a2 / max(d, TINY);
}

// half vectors of the isotropic GGX distribution as seen from wo (Heitz 2018): density
// G1(wo) max(0, wo·h) D(h) / cos θo, the twin of sampling.ggx_visible_half_vector
vec3 ggx_visible_half(vec3 wo, float a, vec2 u) {
    vec3 v = normalize(vec3(a * wo.x, a * wo.y, wo.z));
    float lensq = v.x * v.x + v.y * v.y;
    vec3 t1 = lensq > TINY ? vec3(-v.y, v.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(v, t1);
    float r = sqrt(u.x), phi = 2.0 * PI * u.y;
    float p1 = r * cos(phi), p2 = r * sin(phi);
    float s = 0.5 * (1.0 + v.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * v;
    return normalize(vec3(a * nh.x, a * nh.y, max(nh.z, 1e-6)));
}

float half_pdf_from(float pdf_h, vec3 wi, vec3 wo) {
    vec3 h = upper_half(wi, wo);
    float woh = abs(dot(wo, h));
    return woh > TINY ? pdf_h / (4.0 * woh) : 0.0;
}

// acos to float precision (Abramowitz & Stegun 4.4.46, |error| ≤ 2e-8); GLSL leaves the
// precision of the built-in to the implementation, and Mesa's is far coarser.
float precise_acos(float x) {
    float a = abs(clamp(x, -1.0, 1.0));
    float p = -0.0012624911;
    p = p * a + 0.0066700901;
    p = p * a - 0.0170881256;
    p = p * a + 0.0308918810;
    p = p * a - 0.0501743046;
    p = p * a + 0.0889789874;
    p = p * a - 0.2145988016;
    p = p * a + 1.5707963050;
    float r = sqrt(1.0 - a) * p;
    return x < 0.0 ? PI - r : r;
}

// Lat-long lookup of a world direction (+Y up; u = 0.5 looks along −Z), the map turned by
// `rotation` radians about +Y: the object's lighting and the view's background agree.
vec2 env_uv(vec3 d, float rotation) {
    float c = cos(rotation), s = sin(rotation);
    d = vec3(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    return vec2(0.5 + atan(d.x, -d.z) / (2.0 * PI), precise_acos(clamp(d.y, -1.0, 1.0)) / PI);
}

// asin and atan to float precision too: model files' GLSL calls these three instead of the
// built-ins (brdflab/models/files), so that a file model's render agrees with its CPU formula
// (Mesa's llvmpipe's acos is 1.6e-4 rad off). atan: one Newton step on sin/cos.
float precise_asin(float x) { return 0.5 * PI - precise_acos(x); }
float precise_atan(float y, float x) {
    float a = atan(y, x);
    float c = cos(a), s = sin(a);
    float d = x * c + y * s;  // the length of (x, y), > 0 unless both are 0
    return d > 0.0 ? a + (y * c - x * s) / d : a;
}
float precise_atan(float t) { return precise_atan(t, 1.0); }
vec2 precise_acos(vec2 v) { return vec2(precise_acos(v.x), precise_acos(v.y)); }
vec3 precise_acos(vec3 v) { return vec3(precise_acos(v.x), precise_acos(v.y), precise_acos(v.z)); }
vec2 precise_asin(vec2 v) { return vec2(precise_asin(v.x), precise_asin(v.y)); }
vec3 precise_asin(vec3 v) { return vec3(precise_asin(v.x), precise_asin(v.y), precise_asin(v.z)); }
vec2 precise_atan(vec2 y, vec2 x) { return vec2(precise_atan(y.x, x.x), precise_atan(y.y, x.y)); }
vec3 precise_atan(vec3 y, vec3 x) { return vec3(precise_atan(y.x, x.x), precise_atan(y.y, x.y), precise_atan(y.z, x.z)); }
vec2 precise_atan(vec2 t) { return vec2(precise_atan(t.x), precise_atan(t.y)); }
vec3 precise_atan(vec3 t) { return vec3(precise_atan(t.x), precise_atan(t.y), precise_atan(t.z)); }

// A NaN (a file model's value where it is undefined, or past its loop bound).
float nan_value() { return uintBitsToFloat(0x7fc00000u); }
// w turned by angle a about x (k = 1, 2: ±a) or y (k = 3, 4: ±a); k = 0: w itself. A file
// model's limit at a point where its value is NaN is the mean over k = 1..4 (models/files/model.py).
vec3 nudged(vec3 w, int k, float a) {
    if (k == 0) return w;
    float s = (k == 1 || k == 3) ? sin(a) : -sin(a), c = cos(a);
    return k <= 2 ? vec3(w.x, c * w.y - s * w.z, s * w.y + c * w.z) : vec3(c * w.x + s * w.z, w.y, -s * w.x + c * w.z);
}
