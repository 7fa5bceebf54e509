#version 330 core
// Shading (renderer.py; the units are vebuild.render.lighting's). Unlit ("as photographed"): the
// texture as extracted. Re-lit: the texture is the surface colour (albedo) under ambient light
// plus directional, point and spot lights, each optionally shadowed through the shadow atlas.
// Lighting is computed in linear light and the result encoded to sRGB here, once.
// LIT (0 or 1, set by the renderer) compiles the unlit or the re-lit variant. The renderer also
// compiles a variant per lighting preset and mode (vebuild/render/variants.py): N_LIGHTS with
// LIGHT_TYPE_i and LIGHT_TILE_i unroll the light loop for the preset's lights (types and first
// shadow tiles as constants, so that the compiler drops what a light does not need), and
// TEXTURED and UNOBSERVED_MODE replace the uniforms of those names. Without them, the loop runs
// over n_lights and the uniforms decide (the same results).
#ifndef LIT
#define LIT 1
#endif
#ifndef MAX_LIGHTS
#define MAX_LIGHTS 8
#endif
#ifndef MAX_TILES
#define MAX_TILES 24
#endif
uniform sampler2D atlas;          // an sRGB page: the sampler returns linear values
uniform bool textured;
uniform vec3 ambient;
uniform vec3 eye;                 // camera centre, world
uniform int n_lights;
uniform vec4 light_colour[MAX_LIGHTS];     // rgb irradiance at 1 m, w = type (0 dir, 1 point, 2 spot)
uniform vec4 light_position[MAX_LIGHTS];   // xyz, w = first shadow tile (-1: casts none)
uniform vec4 light_direction[MAX_LIGHTS];  // xyz where the light travels, w = cos(outer cone)
uniform float light_cos_inner[MAX_LIGHTS];
uniform sampler2DShadow shadow_atlas;
uniform mat4 shadow_matrix[MAX_TILES];     // world -> the tile's clip space
uniform vec4 shadow_rect[MAX_TILES];       // the tile in atlas coordinates: x0, y0, width, height
uniform vec2 shadow_texel[MAX_TILES];      // world size of one shadow texel: x at 1 m (y = 1) or flat (y = 0)
uniform sampler2D unseen_mask;    // R8: 1 where no photo saw the texel (vebuild.render.observed)
uniform int unobserved_mode;      // 0 off, 1 hatch, 2 tint
uniform vec3 unobserved_colour;   // linear
uniform float unobserved_strength;
uniform float hatch_period;       // m between stripes along an axis-aligned face
uniform float hatch_duty;         // share of the period a stripe covers
uniform int highlight_node;                // -1: none
#ifndef TEXTURED
#define TEXTURED textured
#endif
#ifndef UNOBSERVED_MODE
#define UNOBSERVED_MODE unobserved_mode
#endif
uniform vec3 highlight_colour;
in vec3 v_world;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_colour;
flat in int v_node;
layout(location = 0) out vec4 out_colour;

vec3 to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

#if LIT
float shadow_factor(int tile, vec3 P, vec3 N, float dist) {
    // Normal offset (1.5 shadow texels along the normal) keeps a lit surface from shadowing itself.
    float texel = shadow_texel[tile].x * (shadow_texel[tile].y > 0.5 ? dist : 1.0);
    vec4 c = shadow_matrix[tile] * vec4(P + N * (1.5 * texel), 1.0);
    if (c.w <= 0.0) return 1.0;
    vec3 ndc = c.xyz / c.w;
    if (abs(ndc.x) > 1.0 || abs(ndc.y) > 1.0 || ndc.z > 1.0) return 1.0;  // outside the light's map
    vec4 r = shadow_rect[tile];
    vec2 size = vec2(textureSize(shadow_atlas, 0));
    vec2 uv = r.xy + (ndc.xy * 0.5 + 0.5) * r.zw;
    vec2 lo = r.xy + 1.5 / size, hi = r.xy + r.zw - 1.5 / size;  // taps stay inside the tile
    float ref = ndc.z * 0.5 + 0.5;
    float s = 0.0;
    // Four bilinear comparisons half a texel apart: a 3x3-texel percentage-closer filter.
    for (int k = 0; k < 4; ++k) {
        vec2 o = vec2((k & 1) == 0 ? -0.5 : 0.5, (k & 2) == 0 ? -0.5 : 0.5) / size;
        s += texture(shadow_atlas, vec3(clamp(uv + o, lo, hi), ref));
    }
    return s * 0.25;
}

int cube_face(vec3 d) {  // +x, -x, +y, -y, +z, -z: the order of a point light's six tiles
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x > 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y > 0.0 ? 2 : 3;
    return d.z > 0.0 ? 4 : 5;
}

// Irradiance from light i of the given type (0 directional, 1 point, 2 spot) whose first shadow
// tile is `tile` (-1: casts none), on a surface at v_world with unit normal N facing the eye.
vec3 light_term(int i, int type, int tile, vec3 N) {
    vec3 L;
    float fall = 1.0, dist = 1.0;
    if (type == 0) {
        L = -light_direction[i].xyz;
    } else {
        vec3 d = light_position[i].xyz - v_world;
        dist = max(length(d), 1e-4);
        L = d / dist;
        fall = 1.0 / (dist * dist);
        if (type == 2)
            fall *= smoothstep(light_direction[i].w, light_cos_inner[i], dot(-L, light_direction[i].xyz));
    }
    float ndl = dot(N, L);
    if (ndl <= 0.0 || fall <= 0.0) return vec3(0.0);
    float s = 1.0;
    if (tile >= 0) {
        if (type == 1) tile += cube_face(-L);
        s = shadow_factor(tile, v_world, N, dist);
    }
    return light_colour[i].rgb * (ndl * fall * s);
}
#endif

void main() {
    vec3 albedo = TEXTURED ? texture(atlas, v_uv).rgb : v_colour;
    vec3 colour = albedo;
#if !LIT
    // Untextured faces would be one flat colour: shade them by the angle to the eye so that
    // shapes read (a face squarely in view at full colour, at grazing angles half of it).
    if (!TEXTURED) colour *= 0.5 + 0.5 * abs(dot(normalize(v_normal), normalize(eye - v_world)));
#endif
#if LIT
    {
        vec3 N = normalize(v_normal);
        if (dot(N, eye - v_world) < 0.0) N = -N;  // a face seen from behind is lit on that side
        vec3 E = ambient;
#ifdef N_LIGHTS
#if N_LIGHTS > 0
        E += light_term(0, LIGHT_TYPE_0, LIGHT_TILE_0, N);
#endif
#if N_LIGHTS > 1
        E += light_term(1, LIGHT_TYPE_1, LIGHT_TILE_1, N);
#endif
#if N_LIGHTS > 2
        E += light_term(2, LIGHT_TYPE_2, LIGHT_TILE_2, N);
#endif
#if N_LIGHTS > 3
        E += light_term(3, LIGHT_TYPE_3, LIGHT_TILE_3, N);
#endif
#if N_LIGHTS > 4
        E += light_term(4, LIGHT_TYPE_4, LIGHT_TILE_4, N);
#endif
#if N_LIGHTS > 5
        E += light_term(5, LIGHT_TYPE_5, LIGHT_TILE_5, N);
#endif
#if N_LIGHTS > 6
        E += light_term(6, LIGHT_TYPE_6, LIGHT_TILE_6, N);
#endif
#if N_LIGHTS > 7
        E += light_term(7, LIGHT_TYPE_7, LIGHT_TILE_7, N);
#endif
#else
        for (int i = 0; i < n_lights; ++i)
            E += light_term(i, int(light_colour[i].w + 0.5), int(light_position[i].w), N);
#endif
        colour = albedo * E;
    }
#endif
    // Texels no photo saw (observed.py): striped (hatch) or tinted. The stripes are the planes
    // x + y + z = const in world space, so they stay put on the surfaces as the camera moves; each
    // is box-filtered over the pixel's footprint (fwidth), and where the period shrinks below ~4
    // pixels the stripes fade into their average, an even tint. Derivatives and the mask's sample
    // are taken outside the branch (uniform control flow).
#if !defined(UNOBSERVED_OFF)
    float unseen = texture(unseen_mask, v_uv).r;
    float s = (v_world.x + v_world.y + v_world.z) / (hatch_period * 1.41421356);
    float ds = max(fwidth(s), 1e-6);
    if (TEXTURED && UNOBSERVED_MODE > 0 && unseen > 0.5) {
        float k = 1.0;
        if (UNOBSERVED_MODE == 1) {
            float tri = abs(fract(s) - 0.5);  // 0 at a stripe's centre, 0.5 midway between stripes
            float cover = clamp((0.5 * hatch_duty - tri) / ds + 0.5, 0.0, 1.0);
            k = mix(cover, hatch_duty, smoothstep(0.125, 0.25, ds));
        }
        colour = mix(colour, unobserved_colour, unobserved_strength * k);
    }
#endif
    if (v_node == highlight_node) colour = mix(colour, highlight_colour, 0.5);
    out_colour = vec4(to_srgb(colour), 1.0);
}
