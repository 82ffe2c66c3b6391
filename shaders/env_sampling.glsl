// Environment importance sampling by luminance: the GLSL twin of
// brdflab/lighting/env_sampling.py (piecewise-constant density per texel; a row from the
// marginal CDF, a column from that row's conditional CDF by binary search, then a point
// uniform in the texel's solid angle). `rotation` turns the map about +Y as env_uv does.
uniform sampler2D u_env_marginal;  // R32F, H × 1: CDF over rows at each row's lower edge
uniform sampler2D u_env_table;     // RG32F, W × H: (row's CDF at the texel's right edge, density per sr)

// first texel of row `row` whose CDF value exceeds u (the last if none), and the lower edge
int env_cdf_search(sampler2D cdf, int row, int n, float u, out float lower) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (texelFetch(cdf, ivec2(mid, row), 0).r > u) hi = mid; else lo = mid + 1;
    }
    lower = lo > 0 ? texelFetch(cdf, ivec2(lo - 1, row), 0).r : 0.0;
    return lo;
}

float env_fraction(float u, float lower, float upper) {
    return upper > lower ? clamp((u - lower) / (upper - lower), 0.0, 1.0) : 0.5;
}

// a world direction drawn with density env_density(d, rotation)
vec3 env_sample(vec2 u, float rotation) {
    ivec2 size = textureSize(u_env_table, 0);
    float lower;
    int row = env_cdf_search(u_env_marginal, 0, size.y, u.x, lower);
    float t_row = env_fraction(u.x, lower, texelFetch(u_env_marginal, ivec2(row, 0), 0).r);
    int col = env_cdf_search(u_env_table, row, size.x, u.y, lower);
    float t_col = env_fraction(u.y, lower, texelFetch(u_env_table, ivec2(col, row), 0).r);
    float cos_top = cos(PI * float(row) / float(size.y));
    float cos_bottom = cos(PI * float(row + 1) / float(size.y));
    float cos_theta = mix(cos_top, cos_bottom, t_row);
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    float phi = ((float(col) + t_col) / float(size.x) - 0.5) * 2.0 * PI;
    vec3 m = vec3(sin_theta * sin(phi), cos_theta, -sin_theta * cos(phi));  // the map's frame
    float c = cos(rotation), s = sin(rotation);
    return vec3(c * m.x - s * m.z, m.y, s * m.x + c * m.z);  // env_uv's turn, undone
}

// the texel of a lat-long grid of `size` texels that map coordinates uv (env_uv) fall in
ivec2 latlong_texel(vec2 uv, ivec2 size) { return clamp(ivec2(floor(uv * vec2(size))), ivec2(0), size - 1); }

// the map texel that map coordinates uv fall in: its density per steradian is the table's .g
ivec2 env_texel(vec2 uv) { return latlong_texel(uv, textureSize(u_env_table, 0)); }
