// The generic tabulated sampler of models read from files: the GLSL twin of
// brdflab/models/files/sampler.py (same half-vector cells, views, cosine share and density).
// u_tab layer s holds lobe slot s: row = a tabulated view, texel x = a cell of h (θ-major,
// TAB_PHI cells per θ ring, θ edges at (π/2)(i/TAB_THETA)²); .r = the row's CDF up to and
// with the cell, .g = the density of h there (per steradian). u_tab_aniso[s] > 0.5: rows
// are (view θ, view φ) pairs.
uniform sampler2DArray u_tab;
uniform float u_tab_aniso[N_TAB];

const int TAB_THETA = 64;
const int TAB_PHI = 128;
const int TAB_CELLS = TAB_THETA * TAB_PHI;
const int TAB_VIEWS = 24;
const int TAB_VIEW_PHI = 12;
const float TAB_COSINE = 0.05;
const float TAB_TOP_VIEW = 1.5533430342749532;  // 89°

// the (up to four) tabulated views around wo: rows, weights and the view azimuths
int tab_views(int slot, vec3 wo, out int rows[4], out float weights[4], out float phis[4]) {
    float theta = precise_acos(clamp(wo.z, -1.0, 1.0));
    float x = clamp(theta / TAB_TOP_VIEW * float(TAB_VIEWS - 1), 0.0, float(TAB_VIEWS - 1));
    int i0 = min(int(floor(x)), TAB_VIEWS - 2);
    float ti = x - float(i0);
    float phi = atan(wo.y, wo.x);
    phi = phi < 0.0 ? phi + 2.0 * PI : phi;
    if (u_tab_aniso[slot] < 0.5) {
        rows[0] = i0; weights[0] = 1.0 - ti; phis[0] = phi;
        rows[1] = i0 + 1; weights[1] = ti; phis[1] = phi;
        return 2;
    }
    float y = phi / (2.0 * PI) * float(TAB_VIEW_PHI);
    int j0 = int(floor(y)) % TAB_VIEW_PHI;
    float tj = y - floor(y);
    int k = 0;
    for (int di = 0; di < 2; di++) {
        for (int dj = 0; dj < 2; dj++) {
            int j = (j0 + dj) % TAB_VIEW_PHI;
            rows[k] = (i0 + di) * TAB_VIEW_PHI + j;
            weights[k] = (di == 0 ? 1.0 - ti : ti) * (dj == 0 ? 1.0 - tj : tj);
            phis[k] = 0.0;
            k++;
        }
    }
    return 4;
}

vec3 tab_rotate(vec3 w, float angle) {
    float c = cos(angle), s = sin(angle);
    return vec3(c * w.x - s * w.y, s * w.x + c * w.y, w.z);
}

vec3 sample_tab(int slot, vec3 wo, vec2 u) {
    if (u.y < TAB_COSINE) return cosine_hemisphere(vec2(u.x, u.y / TAB_COSINE));
    u.y = (u.y - TAB_COSINE) / (1.0 - TAB_COSINE);
    int rows[4]; float weights[4]; float phis[4];
    int n = tab_views(slot, wo, rows, weights, phis);
    int row = rows[n - 1];
    float rotation = phis[n - 1];
    float below = 0.0;
    for (int k = 0; k < n; k++) {  // pick a view by its weight, reusing u.x
        if (u.x < below + weights[k]) {
            row = rows[k];
            rotation = phis[k];
            u.x = weights[k] > 0.0 ? (u.x - below) / weights[k] : u.x;
            break;
        }
        below += weights[k];
    }
    u = clamp(u, 0.0, 0.99999994);
    int lo = 0, hi = TAB_CELLS - 1;  // the first cell whose CDF exceeds u.x
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (texelFetch(u_tab, ivec3(mid, row, slot), 0).r > u.x) hi = mid; else lo = mid + 1;
    }
    float c_hi = texelFetch(u_tab, ivec3(lo, row, slot), 0).r;
    float c_lo = lo > 0 ? texelFetch(u_tab, ivec3(lo - 1, row, slot), 0).r : 0.0;
    float r = c_hi > c_lo ? clamp((u.x - c_lo) / (c_hi - c_lo), 0.0, 1.0) : 0.5;
    int it = lo / TAB_PHI, ip = lo - it * TAB_PHI;
    float t0 = float(it) / float(TAB_THETA), t1 = float(it + 1) / float(TAB_THETA);
    float c0 = cos(0.5 * PI * t0 * t0), c1 = cos(0.5 * PI * t1 * t1);
    float cos_t = c0 + r * (c1 - c0);
    float phi = (float(ip) + u.y) * (2.0 * PI / float(TAB_PHI));
    float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
    vec3 h = tab_rotate(vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t), rotation);
    return 2.0 * dot(wo, h) * h - wo;
}

float pdf_tab(int slot, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    vec3 h = normalize(wi + wo);
    int rows[4]; float weights[4]; float phis[4];
    int n = tab_views(slot, wo, rows, weights, phis);
    float p = 0.0;
    for (int k = 0; k < n; k++) {
        vec3 local = tab_rotate(h, -phis[k]);
        float theta = precise_acos(clamp(local.z, -1.0, 1.0));
        int it = min(int(sqrt(theta / (0.5 * PI)) * float(TAB_THETA)), TAB_THETA - 1);
        float phi = atan(local.y, local.x);
        phi = phi < 0.0 ? phi + 2.0 * PI : phi;
        int ip = min(int(phi / (2.0 * PI) * float(TAB_PHI)), TAB_PHI - 1);
        p += weights[k] * texelFetch(u_tab, ivec3(it * TAB_PHI + ip, rows[k], slot), 0).g;
    }
    float woh = abs(dot(wo, h));
    float tabulated = woh > 1e-12 ? p / (4.0 * woh) : 0.0;
    return (1.0 - TAB_COSINE) * tabulated + TAB_COSINE * wi.z / PI;
}
