#version 330 core
// Pass 2: project a texel into the photo, test it against the ID buffer, sample the photo over
// its footprint and weight it (definitions: vebuild/texture/__init__.py).
//
// The lens (k1, the division model of vebuild/camera.py): the texel is projected by the pinhole
// K and tested in the ID buffer, which covers the photo's undistorted bounds (its pixel corner
// (0, 0) at id_origin in K's pinhole pixels: vebuild/texture/lens.py); then its pinhole pixel and
// footprint are distorted in closed form, x_d = x_u * 2 / (1 + sqrt(1 - 4 k1 |x_u|^2)), and the
// photo is sampled where the lens put the texel: one resampling of the photo as it was recorded.
// With k1 = 0 the ID buffer is the photo's own frame and nothing is distorted.
//
// MODE 0 accumulate (additive blending): 0 = (sum w l/g, sum w), 1 = (sum w^s (c-l)/g, sum w^s)
//        over kept views, 2 = (sum v c/g, sum v) over dropped views with v = w / (the texel's best
//        weight): each v < drop_ratio < 1, so the sums fit the half floats they are kept in,
//        3 = (kept, dropped) counts (half floats: exact to 2048)
// MODE 1 one view: 0 = (c, w), 1 = (l, face id where seen, else 0), 2 = accumulated low band so far (rgb, seen before)
// MODE 2 best weight (max blending): 0 = w
// MODE 3 geometry: 0 = (face, position), 1 = (normal, 1); into a one-channel target, the face alone
// A texel the photo does not see is discarded: it adds nothing, and occlusion queries count the
// seen texels of each face.
#define MAX_LEVELS 16
uniform mat3 K;
uniform mat3 R;
uniform vec3 C;
uniform vec2 image_size;     // the photo's size in pixels
uniform float k1;            // the photo's lens distortion (k1, k2); 0, 0: a pinhole
uniform float k2;
uniform vec2 id_origin;      // the ID buffer's pixel corner (0, 0) in the photo's pinhole pixels
uniform vec2 id_size;        // the ID buffer's size in pixels (the photo's for a pinhole)
uniform float weight_scale;   // photo pixels per ID-buffer pixel (2 for a half-size pre-pass)
uniform float depth_tolerance;
uniform sampler2D id_depth;   // RG32F (face id, depth), nearest
uniform sampler2D photo;      // level 0, sRGB, linear filtering
uniform sampler2D pyramid_odd;
uniform sampler2D pyramid_even;
uniform vec2 odd_size;
uniform vec2 even_size;
uniform int levels;
uniform vec2 level_size[MAX_LEVELS];
uniform float level_y0[MAX_LEVELS];
uniform float detail_levels;
uniform vec3 inverse_gain;
uniform float sharpness;
uniform float drop_ratio;
uniform sampler2D best_weight;  // R32F per atlas texel (MODE 0 with drop_ratio > 0)
uniform sampler2D accumulated;  // target 0 of MODE 0 (MODE 1)
uniform float atlas_scale;

in vec3 v_position;
in vec3 v_normal;
flat in float v_face;
flat in vec3 v_eu;
flat in vec3 v_ev;
layout(location = 0) out vec4 out0;
layout(location = 1) out vec4 out1;
layout(location = 2) out vec4 out2;
layout(location = 3) out vec4 out3;

vec3 sample_level(int k, vec2 p) {
    if (k == 0) return texture(photo, p / image_size).rgb;
    vec2 q = clamp(p / exp2(float(k)), vec2(0.5), level_size[k] - 0.5) + vec2(0.0, level_y0[k]);
    if ((k & 1) == 1) return texture(pyramid_odd, q / odd_size).rgb;
    return texture(pyramid_even, q / even_size).rgb;
}

vec3 trilinear(vec2 p, float lod) {
    lod = clamp(lod, 0.0, float(levels - 1));
    int k = int(floor(lod));
    float t = lod - float(k);
    vec3 c = sample_level(k, p);
    if (t > 0.0 && k + 1 < levels) c = mix(c, sample_level(k + 1, p), t);
    return c;
}

bool in_photo(vec2 p) {
    return all(greaterThanEqual(p, vec2(0.0))) && all(lessThan(p, image_size));
}

bool same_face(vec2 q) {  // q in ID-buffer pixels
    if (any(lessThan(q, vec2(0.0))) || any(greaterThanEqual(q, id_size))) return false;
    return texelFetch(id_depth, ivec2(floor(q)), 0).r == v_face;
}

void main() {
    out0 = vec4(0.0); out1 = vec4(0.0); out2 = vec4(0.0); out3 = vec4(0.0);
#if MODE == 3
    out0 = vec4(v_face, v_position);
    out1 = vec4(normalize(v_normal), 1.0);
    return;
#else
    vec3 x = R * (v_position - C);
    if (x.z <= 0.0) discard;
    vec3 to_camera = C - v_position;
    float cos_theta = dot(normalize(v_normal), to_camera) / length(to_camera);
    if (cos_theta <= 0.0) discard;
    vec3 h = K * x;
    vec2 p = h.xy / h.z;  // the pinhole's pixel
    vec2 q = p - id_origin;  // ... in the ID buffer
    if (any(lessThan(q, vec2(0.0))) || any(greaterThanEqual(q, id_size))) discard;
    vec2 id_z = texelFetch(id_depth, ivec2(floor(q)), 0).rg;
    if (id_z.r != v_face || x.z > (1.0 + depth_tolerance) * id_z.g) discard;
    // The Jacobian of the projection: pixels per metre along the texel's steps e_u, e_v.
    mat3 Kc = K;
    vec3 ju = vec3(Kc[0][0], Kc[1][0], Kc[2][0]);  // first row of K
    vec3 jv = vec3(Kc[0][1], Kc[1][1], Kc[2][1]);  // second row of K
    vec3 du = R * v_eu, dv = R * v_ev;
    vec2 a = (vec2(dot(ju, du), dot(jv, du)) - p * du.z) / x.z;
    vec2 b = (vec2(dot(ju, dv), dot(jv, dv)) - p * dv.z) / x.z;
    if (!(same_face(q + a + b) && same_face(q + a - b) && same_face(q - a + b) && same_face(q - a - b))) discard;
    if (k1 != 0.0 || k2 != 0.0) {
        // Where the lens put the pinhole's pixel, and the footprint there: x_d = s x_u with
        // s = 2 / (1 + sqrt(1 - 4 k1 |x_u|^2)) for one term; with two, s solves
        // s = 1 + k1 s^2 r^2 + k2 s^4 r^4 (r = |x_u|; Newton's method from s = 1, as
        // vebuild/camera.py's distortion_derivatives). Its Jacobian is s I + g x_u x_u^T with
        // g = 2 ds/dr^2 = 2 (k1 s^2 + 2 k2 s^4 r^2) / F_s, F_s = 1 - 2 k1 s r^2 - 4 k2 s^3 r^4
        // (the same on pixels, as both sides are divided by f).
        float f = Kc[0][0];
        vec2 c = vec2(Kc[2][0], Kc[2][1]);
        vec2 xu = (p - c) / f;
        float r2 = dot(xu, xu);
        float s;
        float g;
        if (k2 == 0.0) {
            float disc = 1.0 - 4.0 * k1 * r2;
            if (disc <= 0.0) discard;  // beyond the field of a pincushion lens: in no photo
            float root = sqrt(disc);
            s = 2.0 / (1.0 + root);
            g = 2.0 * k1 * s * s / root;
        } else {
            s = 1.0;
            float Fs = 1.0;
            for (int it = 0; it < 40; ++it) {
                Fs = 1.0 - 2.0 * k1 * s * r2 - 4.0 * k2 * s * s * s * r2 * r2;
                if (Fs <= 0.0) discard;  // past the rim, where the lens stops opening out: in no photo
                s -= (s - 1.0 - k1 * s * s * r2 - k2 * s * s * s * s * r2 * r2) / Fs;
            }
            Fs = 1.0 - 2.0 * k1 * s * r2 - 4.0 * k2 * s * s * s * r2 * r2;
            if (Fs <= 0.0 || s <= 0.0) discard;
            g = 2.0 * (k1 * s * s + 2.0 * k2 * s * s * s * s * r2) / Fs;
        }
        p = c + f * s * xu;
        a = s * a + g * dot(xu, a) * xu;
        b = s * b + g * dot(xu, b) * xu;
        // The footprint must lie in the photo, as the ID buffer's frame is the photo's for a pinhole.
        if (!(in_photo(p + a + b) && in_photo(p + a - b) && in_photo(p - a + b) && in_photo(p - a - b))) discard;
    }
    float w = sqrt(abs(a.x * b.y - a.y * b.x)) * cos_theta * weight_scale;
#if MODE == 2
    out0 = vec4(w, 0.0, 0.0, 0.0);
    return;
#else
    float lod = log2(max(max(length(a), length(b)), 1e-6));
    vec3 c = trilinear(p, lod);
    vec3 l = trilinear(p, lod + detail_levels);
#if MODE == 1
    out0 = vec4(c, w);
    out1 = vec4(l, v_face);
    vec4 acc = texelFetch(accumulated, ivec2(floor(gl_FragCoord.xy / atlas_scale)), 0);
    out2 = acc.a > 0.0 ? vec4(acc.rgb / acc.a, 1.0) : vec4(0.0);
#else
    float best = drop_ratio > 0.0 ? texelFetch(best_weight, ivec2(gl_FragCoord.xy), 0).r : 0.0;
    bool keep = drop_ratio <= 0.0 || w >= drop_ratio * best;  // a dropped view has best > w >= 0
    if (keep) {
        float ws = pow(clamp(w, 1e-4, 1e4), sharpness);
        out0 = vec4(w * l * inverse_gain, w);
        out1 = vec4(ws * (c - l) * inverse_gain, ws);
        out3 = vec4(1.0, 0.0, 0.0, 0.0);
    } else {
        float v = w / best;
        out2 = vec4(v * c * inverse_gain, v);
        out3 = vec4(0.0, 1.0, 0.0, 0.0);
    }
#endif
#endif
#endif
}
