// Shows an accumulated float image: divide by the sample count, expose, tone map, sRGB.
// Where no surface was drawn: the environment map seen through the camera, or a flat colour.
#ifdef VERTEX
out vec2 v_uv;
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    v_uv = 0.5 * p + 0.5;
    gl_Position = vec4(p, 0.0, 1.0);
}
#else
in vec2 v_uv;
uniform sampler2D u_image;
uniform float u_scale;      // 2^exposure / samples
uniform bool u_reinhard;
uniform float u_gamma;      // 0: the sRGB curve; otherwise x^(1/gamma)
uniform vec3 u_background;
uniform bool u_show_env;
uniform sampler2D u_env;
uniform float u_env_rotation;
uniform float u_env_scale;  // 2^exposure
uniform mat4 u_inverse_view_projection;
uniform vec3 u_camera_position;
// comparing two images of the same scene (original | fit): 0 off, 1 split at u_split, 2 difference
uniform int u_compare;
uniform sampler2D u_image_b;
uniform float u_scale_b;
uniform float u_split;
out vec4 frag;

vec3 heat(float t) {  // 0 black → red → yellow → white at 1; the legend's is object_view.difference_colour
    return clamp(vec3(3.0 * t, 3.0 * t - 1.0, 3.0 * t - 2.0), 0.0, 1.0);
}

void main() {
    vec4 c = texture(u_image, v_uv);
    float scale = u_scale;
    if (u_compare == 1) {
        if (abs(v_uv.x - u_split) * float(textureSize(u_image, 0).x) < 1.0) { frag = vec4(1.0); return; }
        if (v_uv.x > u_split) { c = texture(u_image_b, v_uv); scale = u_scale_b; }
    } else if (u_compare == 2 && c.a > 0.0) {
        const vec3 LUM = vec3(0.2126, 0.7152, 0.0722);
        float a = max(dot(c.rgb * u_scale, LUM), 0.0);
        float b = max(dot(texture(u_image_b, v_uv).rgb * u_scale_b, LUM), 0.0);
        frag = vec4(heat(abs(a - b) / max(max(a, b), 1e-6)), 1.0);  // relative difference, 1 = 100 %
        return;
    }
    vec3 x;
    if (c.a > 0.0) {
        x = max(c.rgb * scale, 0.0);
    } else if (u_show_env) {
        vec4 p = u_inverse_view_projection * vec4(2.0 * v_uv - 1.0, 1.0, 1.0);
        vec3 d = normalize(p.xyz / p.w - u_camera_position);
        x = max(textureLod(u_env, env_uv(d, u_env_rotation), 0.0).rgb * u_env_scale, 0.0);
    } else {
        frag = vec4(u_background, 1.0);
        return;
    }
    if (u_reinhard) x = x / (1.0 + x);
    x = clamp(x, 0.0, 1.0);
    vec3 srgb = mix(12.92 * x, 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), x));
    frag = vec4(u_gamma > 0.0 ? pow(x, vec3(1.0 / u_gamma)) : srgb, 1.0);
}
#endif
