// Lobe viewer: a geodesic hemisphere of directions wo, each moved to radius
// transfer(f(wi, wo) [· cos θo]). SOURCE_TEXTURE: values from a (θo, φo) texture that the
// CPU refreshes when wi changes (measured and simulated sources); else the material's GLSL.
in vec3 in_direction;
uniform vec3 u_wi;
uniform int u_transfer;      // 0 linear, 1 cube root, 2 log(1 + x)
uniform bool u_cosine;       // multiply by cos θo
uniform int u_channel;       // 0, 1, 2 or 3 = luminance
uniform float u_gain;
uniform mat4 u_view_projection;
uniform vec3 u_eye;          // the camera, in the lobe's frame
uniform float u_depth_bias;  // depth only: this far nearer the eye, along its view ray
#ifdef SOURCE_TEXTURE
uniform sampler2D u_values;  // x = φo / 2π, y = θo / (π/2)
#endif
out vec3 g_position;

float channel_value(vec3 f) {
    if (u_channel == 3) return dot(f, vec3(0.2126, 0.7152, 0.0722));
    return f[u_channel];
}

void main() {
    vec3 wo = normalize(in_direction);
#ifdef SOURCE_TEXTURE
    float phi = atan(wo.y, wo.x);
    if (phi < 0.0) phi += 2.0 * PI;
    vec3 f = texture(u_values, vec2(phi / (2.0 * PI), precise_acos(wo.z) / (0.5 * PI))).rgb;
#else
    vec3 f = material_eval(u_wi, wo);
#endif
    float v = max(channel_value(f), 0.0) * (u_cosine ? max(wo.z, 0.0) : 1.0);
    float r = u_transfer == 1 ? pow(v, 1.0 / 3.0) : (u_transfer == 2 ? log(1.0 + v) : v);
    g_position = u_gain * r * wo;
    // moved along the ray from the eye, the vertex projects to the same pixel: only its depth
    // changes (shading uses g_position)
    vec3 to_eye = u_eye - g_position;
    float eye_distance = length(to_eye);
    vec3 tested = g_position + (eye_distance > 0.0 ? min(u_depth_bias, 0.5 * eye_distance) / eye_distance : 0.0) * to_eye;
    gl_Position = u_view_projection * vec4(tested, 1.0);
}
