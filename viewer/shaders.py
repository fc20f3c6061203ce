"""GLSL 3.30 core sources. Kept apart from the Python that binds them so both stay short."""

CAPSULE_VS = """
#version 330
in vec3 in_dir;      // unit direction of the capsule vertex
in float in_end;     // 0: parent end a, 1: child end b
in vec3 i_a;
in vec3 i_b;
in float i_radius;
in vec4 i_color;
uniform mat4 u_viewproj;
uniform float u_inflate;  // translucent shells are drawn slightly larger than the bones
out vec3 v_normal;
out vec3 v_world;
out vec4 v_color;
void main() {
    vec3 axis = i_b - i_a;
    float len = length(axis);
    vec3 y = len > 1e-6 ? axis / len : vec3(0.0, 1.0, 0.0);
    // Any basis around the axis will do: the capsule is round, its roll never shows.
    vec3 helper = abs(y.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
    vec3 x = normalize(cross(helper, y));
    vec3 z = cross(x, y);
    vec3 n = x * in_dir.x + y * in_dir.y + z * in_dir.z;
    vec3 p = mix(i_a, i_b, in_end) + i_radius * u_inflate * n;
    v_normal = n;
    v_world = p;
    v_color = i_color;
    gl_Position = u_viewproj * vec4(p, 1.0);
}
"""

CAPSULE_FS = """
#version 330
in vec3 v_normal;
in vec3 v_world;
in vec4 v_color;
uniform vec3 u_eye;
out vec4 f_color;
void main() {
    vec3 n = normalize(v_normal);
    // A head light tilted upwards: bones are lit from wherever the user orbits to.
    vec3 l = normalize(normalize(u_eye - v_world) + vec3(0.0, 0.6, 0.0));
    float diffuse = max(dot(n, l), 0.0);
    float hemi = 0.5 + 0.5 * n.y;
    vec3 h = normalize(l + normalize(u_eye - v_world));
    float spec = pow(max(dot(n, h), 0.0), 32.0) * 0.25;
    vec3 rgb = v_color.rgb * (0.28 + 0.22 * hemi + 0.6 * diffuse) + vec3(spec);
    f_color = vec4(rgb, v_color.a);
}
"""

GRID_VS = """
#version 330
in vec3 in_pos;
in float in_shade;
uniform mat4 u_viewproj;
out float v_shade;
out vec3 v_world;
void main() {
    v_shade = in_shade;
    v_world = in_pos;
    gl_Position = u_viewproj * vec4(in_pos, 1.0);
}
"""

GRID_FS = """
#version 330
in float v_shade;
in vec3 v_world;
uniform vec3 u_center;
uniform vec3 u_background;
out vec4 f_color;
void main() {
    // Fade into the background with distance, so the grid has no hard edge.
    float fade = clamp(1.0 - length(v_world.xz - u_center.xz) / 6.0, 0.0, 1.0);
    f_color = vec4(mix(u_background, vec3(v_shade), 0.55 * fade), 1.0);
}
"""

SHADOW_VS = """
#version 330
in vec2 in_corner;   // unit quad corner in [0, 1]^2
in vec3 i_center;    // floor point under a performer's hips
uniform mat4 u_viewproj;
uniform float u_radius;
out vec2 v_uv;
void main() {
    v_uv = in_corner * 2.0 - 1.0;
    vec3 p = vec3(i_center.x + v_uv.x * u_radius, 0.002, i_center.z + v_uv.y * u_radius);
    gl_Position = u_viewproj * vec4(p, 1.0);
}
"""

SHADOW_FS = """
#version 330
in vec2 v_uv;
out vec4 f_color;
void main() {
    float a = 0.45 * (1.0 - smoothstep(0.2, 1.0, length(v_uv)));
    f_color = vec4(0.0, 0.0, 0.0, a);
}
"""

TEXT_VS = """
#version 330
in vec2 in_corner;
in vec4 i_rect;      // x, y, w, h in pixels, origin top-left
in vec4 i_uv;        // u0, v0, u1, v1 in the atlas
in vec4 i_color;
uniform vec2 u_screen;
out vec2 v_uv;
out vec4 v_color;
void main() {
    vec2 px = i_rect.xy + in_corner * i_rect.zw;
    v_uv = mix(i_uv.xy, i_uv.zw, in_corner);
    v_color = i_color;
    gl_Position = vec4(px.x / u_screen.x * 2.0 - 1.0, 1.0 - px.y / u_screen.y * 2.0, 0.0, 1.0);
}
"""

TEXT_FS = """
#version 330
in vec2 v_uv;
in vec4 v_color;
uniform sampler2D u_atlas;
out vec4 f_color;
void main() {
    f_color = vec4(v_color.rgb, v_color.a * texture(u_atlas, v_uv).r);
}
"""
