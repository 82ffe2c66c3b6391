// A measured isotropic BRDF on MERL's grid, as a 3-D texture: x = φd (folded to [0, π)),
// y = θd, z = θh (MERL's square-root spacing). Trilinear filtering by the hardware.
uniform sampler3D u_table;
uniform vec3 u_table_size;   // (φd bins, θd bins, θh bins)

vec3 measured_eval(vec3 wi, vec3 wo) {
    vec3 h = normalize(wi + wo);
    float theta_h = precise_acos(h.z);
    float phi_h = atan(h.y, h.x);
    float c = cos(-phi_h), s = sin(-phi_h);
    vec3 d = vec3(c * wi.x - s * wi.y, s * wi.x + c * wi.y, wi.z);
    c = cos(-theta_h); s = sin(-theta_h);
    d = vec3(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    float theta_d = precise_acos(d.z);
    float phi_d = atan(d.y, d.x);
    if (phi_d < 0.0) phi_d += PI;
    // bin k's value sits at its centre (index k + 1/2, CONVENTIONS.md): idx puts centres on integers
    vec3 idx = vec3(phi_d / PI * u_table_size.x,
                    theta_d / (0.5 * PI) * u_table_size.y,
                    sqrt(clamp(theta_h / (0.5 * PI), 0.0, 1.0)) * u_table_size.z) - 0.5;
    idx.yz = clamp(idx.yz, vec2(0.0), u_table_size.yz - 1.0);
    return texture(u_table, (idx + 0.5) / u_table_size).rgb;
}
