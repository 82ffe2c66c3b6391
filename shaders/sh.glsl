// Spherical-harmonics lighting (Kautz, Sloan & Snyder 2002), per pixel, view and light both
// free: rotate the world lighting into the local frame (zyz Euler angles, the y rotation
// as x(−90°)·z(β)·x(+90°) with tabulated band matrices), look up the BRDF product vector
// c(v) in the parabolic map, and take the dot product. Needs SH_ORDER defined.
#define SH_N (SH_ORDER * SH_ORDER)
uniform vec3 u_sh_light[SH_N];        // world-frame lighting coefficients (RGB)
uniform sampler2DArray u_sh_table;    // c_i per channel, packed 4 values per layer
uniform sampler2D u_sh_rx;            // band matrices of Rx(+90°), then of Rx(−90°)
uniform int u_sh_rx_half;             // offset of the Rx(−90°) matrices
#ifdef SH_VERTEX_LIGHT
// per-vertex data computed on the CPU, SH_VERTEX_STRIDE values per vertex, SH_VERTEX_ROW
// vertices per texture row: the (shadowed) world lighting; with SH_FIXED_LIGHT the lighting
// already rotated into the vertex's frame; with SH_FIXED_VIEW the vertex's final colour
flat in int v_vertex;
uniform sampler2D u_sh_vertex_light;
vec3 vertex_value(int i) {
    return texelFetch(u_sh_vertex_light, ivec2(i + SH_VERTEX_STRIDE * (v_vertex % SH_VERTEX_ROW), v_vertex / SH_VERTEX_ROW), 0).rgb;
}
vec3 sh_light(int i) { return vertex_value(i); }
#else
vec3 sh_light(int i) { return u_sh_light[i]; }
#endif

void sh_rotate_z(inout vec3 c[SH_N], float t) {
    for (int l = 1; l < SH_ORDER; l++) {
        for (int m = 1; m <= l; m++) {
            float ca = cos(float(m) * t), sa = sin(float(m) * t);
            int n = l * l + l - m, p = l * l + l + m;
            vec3 a = c[n], b = c[p];
            c[n] = ca * a + sa * b;
            c[p] = -sa * a + ca * b;
        }
    }
}

void sh_rotate_x(inout vec3 c[SH_N], int base) {
    vec3 tmp[2 * SH_ORDER - 1];
    int offset = base;
    for (int l = 1; l < SH_ORDER; l++) {
        int w = 2 * l + 1;
        for (int r = 0; r < w; r++) {
            vec3 s = vec3(0.0);
            for (int k = 0; k < w; k++) s += texelFetch(u_sh_rx, ivec2(offset + r * w + k, 0), 0).r * c[l * l + k];
            tmp[r] = s;
        }
        for (int r = 0; r < w; r++) c[l * l + r] = tmp[r];
        offset += w * w;
    }
}

vec3 sh_shade(mat3 world_to_local_rows_tbn, vec3 wo) {
#ifdef SH_FIXED_VIEW
    return vertex_value(0);
#endif
    // R = rows (t, b, n): local = R · world.  R = Rz(α) Ry(β) Rz(γ)
    vec3 t = world_to_local_rows_tbn[0], b = world_to_local_rows_tbn[1], n = world_to_local_rows_tbn[2];
    float r22 = n.z;
    float beta = precise_acos(r22);
    float alpha, gamma;
    if (abs(sin(beta)) < 1e-6) {
        alpha = r22 > 0.0 ? atan(b.x, t.x) : atan(-b.x, -t.x);
        gamma = 0.0;
    } else {
        alpha = atan(b.z, t.z);
        gamma = atan(n.y, -n.x);
    }
    vec3 c[SH_N];
    for (int i = 0; i < SH_N; i++) c[i] = sh_light(i);
#ifndef SH_FIXED_LIGHT
    sh_rotate_z(c, gamma);
    sh_rotate_x(c, 0);
    sh_rotate_z(c, beta);
    sh_rotate_x(c, u_sh_rx_half);
    sh_rotate_z(c, alpha);
#endif
    vec2 uv = 0.5 * (wo.xy / (1.0 + max(wo.z, 0.0)) + 1.0);
    vec3 color = vec3(0.0);
    for (int layer = 0; layer < (SH_N * 3 + 3) / 4; layer++) {
        vec4 v = texture(u_sh_table, vec3(uv, float(layer)));
        for (int k = 0; k < 4; k++) {
            int idx = layer * 4 + k;
            if (idx >= SH_N * 3) break;
            int i = idx / 3, ch = idx - 3 * i;
            color[ch] += v[k] * c[i][ch];
        }
    }
    return color;
}
