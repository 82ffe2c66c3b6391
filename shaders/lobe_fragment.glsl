// Two-sided headlight shading of the lobe in its colour (alpha for translucency).
in vec3 f_normal;
in vec3 f_position;
uniform vec4 u_color;
uniform vec3 u_eye;
out vec4 frag;
void main() {
    vec3 v = normalize(u_eye - f_position);
    float d = abs(dot(normalize(f_normal), v));
    frag = vec4(u_color.rgb * (0.25 + 0.75 * d), u_color.a);
}
