// SPDX-License-Identifier: Apache-2.0
#pragma once
// GlAttention's GLSL (gl_attention.h): the steps of Lee 2009 chapter 3's pixel stage, numbered as
// there. Each full-screen pass's body defines shade(p), the function of its output texel that the
// fragment and compute programs both run (gl_attention.cpp declares the outputs per implementation).

namespace fovea::render::gl_attention_glsl {

inline constexpr const char* kSlotLayout = R"(
ivec2 slot_texel(int s) { return ivec2(s & 1023, s >> 10); }
// A float's bits as an unsigned integer in the float's order (the radix select's key).
uint sortable(float v) {
  uint b = floatBitsToUint(v);
  return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}
)";

// 1. The G-buffer resampled to the map (resample_grid and resample_rows of gbuffer_resample.cpp): each map
// pixel's box of source pixels (or the one under its centre), colour clamped to [0, 1] per source
// pixel, summed per source column over the rows and then over the columns (the CPU's order), HLS and
// eq. 3.1; ids and the per-object depth nearest. Map rows are stored top row first (texel row y is
// map row y), as the CPU's; the G-buffer's rows are bottom-up.
inline constexpr const char* kResample = R"(
uniform sampler2D u_color, u_depth;
uniform usampler2D u_ids, u_objects;
uniform int u_n, u_objects_count;
uniform ivec2 u_size;
uniform bool u_nearest, u_has_image, u_has_color, u_has_depth, u_has_ids;
uniform float u_near, u_far, u_inv_range;
// Outputs: o_image (L, hue a, hue b, B_d); o_slot (the object's slot + 1; 0: background or not an
// object); o_depth (nearest view depth, for the median).

int ceil_div(int a, int b) { return a >= 0 ? (a + b - 1) / b : -((-a) / b); }
// Source pixels [lo, hi) of map pixel k along an axis of s pixels: centres in [k, k + 1) s / n, so
// lo = ceil(k s / n - 1/2) = ceil((2 k s - n) / 2 n); the centre pixel floor((k + 1/2) s / n).
ivec3 source_range(int k, int s) {
  int lo = clamp(ceil_div(2 * k * s - u_n, 2 * u_n), 0, s);
  int hi = clamp(ceil_div(2 * (k + 1) * s - u_n, 2 * u_n), 0, s);
  int centre = clamp(((2 * k + 1) * s) / (2 * u_n), 0, s - 1);
  if (hi <= lo || u_nearest) { lo = centre; hi = centre + 1; }
  return ivec3(lo, hi, centre);
}
ivec2 texel(int x, int y_top) { return ivec2(x, u_size.y - 1 - y_top); }
float clamped(float c) { return isnan(c) ? 0.0 : clamp(c, 0.0, 1.0); }
uint slot_of(uint id) {
  if (id == 0u) return 0u;
  int lo = 0, hi = u_objects_count;
  while (lo < hi) {
    int mid = (lo + hi) >> 1;
    if (texelFetch(u_objects, slot_texel(mid), 0).r < id) lo = mid + 1; else hi = mid;
  }
  return (lo < u_objects_count && texelFetch(u_objects, slot_texel(lo), 0).r == id) ? uint(lo) + 1u : 0u;
}
// gbuffer_resample.cpp's hls(): lightness, and the hue vector (S cos H, S sin H).
vec3 hls(vec3 c) {
  float mx = max(c.r, max(c.g, c.b)), mn = min(c.r, min(c.g, c.b));
  float l = 0.5 * (mx + mn), chroma = mx - mn;
  if (!(chroma > 1e-6)) return vec3(l, 0.0, 0.0);
  float sat = clamp(chroma / max(1e-6, 1.0 - abs(2.0 * l - 1.0)), 0.0, 1.0);
  float h6;
  if (mx == c.r) { h6 = (c.g - c.b) / chroma; if (h6 < 0.0) h6 += 6.0; }
  else if (mx == c.g) h6 = (c.b - c.r) / chroma + 2.0;
  else h6 = (c.r - c.g) / chroma + 4.0;
  float a = clamp(h6, 0.0, 6.0) * 1.0471975511965976;  // 60 degrees
  return vec3(l, sat * cos(a), sat * sin(a));
}
// The sum of (clamped colour, depth) over source columns [x0, x1) step dx and rows [y0, y1) step dy,
// per column over its rows, then over the columns (the CPU's order when both steps are 1).
vec4 box_sum(int x0, int x1, int dx, int y0, int y1, int dy) {
  vec4 sum = vec4(0.0);
  for (int sx = x0; sx < x1; sx += dx) {
    vec4 column = vec4(0.0);
    for (int sy = y0; sy < y1; sy += dy) {
      ivec2 t = texel(sx, sy);
      if (u_has_color) {
        vec3 c = texelFetch(u_color, t, 0).rgb;
        column.rgb += vec3(clamped(c.r), clamped(c.g), clamped(c.b));
      }
      float d = u_far;  // background (id 0), NaN and no depth plane: the far plane
      if (u_has_depth && (!u_has_ids || texelFetch(u_ids, t, 0).r != 0u)) {
        float raw = texelFetch(u_depth, t, 0).r;
        d = isnan(raw) ? u_far : clamp(raw, u_near, u_far);
      }
      column.a += d;
    }
    sum += column;
  }
  return sum;
}
// A map pixel from its box's sum (HLS and eq. 3.1) and the pixel under its centre (slot, depth).
void finish(ivec3 cx, ivec3 cy, vec4 sum) {
  vec3 rgb = sum.rgb;
  float z = sum.a;
  int count = (cx.y - cx.x) * (cy.y - cy.x);
  float inv = count > 0 ? 1.0 / float(count) : 0.0;
  rgb *= inv;
  z = count > 0 ? z * inv : u_far;
  o_image = vec4(hls(rgb), clamp((z - u_near) * u_inv_range, 0.0, 1.0));  // eq. 3.1
  ivec2 t = texel(cx.z, cy.z);
  uint id = u_has_ids ? texelFetch(u_ids, t, 0).r : 0u;
  o_slot = slot_of(id);
  float raw = texelFetch(u_depth, t, 0).r;
  o_depth = (u_has_depth && id != 0u && !isnan(raw) && !isinf(raw)) ? clamp(raw, u_near, u_far) : u_far;
}
)";
// The fragment pass: one map pixel's whole box per fragment.
inline constexpr const char* kResampleShade = R"(
void shade(ivec2 m) {
  if (!u_has_image) { o_image = vec4(0.0); o_slot = 0u; o_depth = u_far; return; }
  ivec3 cx = source_range(m.x, u_size.x), cy = source_range(m.y, u_size.y);
  finish(cx, cy, box_sum(cx.x, cx.y, 1, cy.x, cy.y, 1));
}
)";
// The compute pass: one 8x8 workgroup per map pixel, each invocation summing every eighth column and
// row of the box, the 64 partial sums added in shared memory (a map pixel of a 1080p frame at 64x64
// is a 30x17 box: one fragment fetching 510 texels thrice is latency-bound where there are only
// n^2 fragments). The sums' order differs from the fragment pass's, by float rounding only.
inline constexpr const char* kResampleCompute = R"(
layout(rgba32f, binding = 0) writeonly uniform image2D u_out0;
layout(r32ui, binding = 1) writeonly uniform uimage2D u_out1;
layout(r32f, binding = 2) writeonly uniform image2D u_out2;
shared vec4 partial[64];
void main() {
  ivec2 m = ivec2(gl_WorkGroupID.xy);
  uint t = gl_LocalInvocationIndex;
  if (!u_has_image) {
    if (t == 0u) {
      imageStore(u_out0, m, vec4(0.0));
      imageStore(u_out1, m, uvec4(0u));
      imageStore(u_out2, m, vec4(u_far, 0.0, 0.0, 0.0));
    }
    return;
  }
  ivec3 cx = source_range(m.x, u_size.x), cy = source_range(m.y, u_size.y);
  ivec2 l = ivec2(gl_LocalInvocationID.xy);
  partial[t] = box_sum(cx.x + l.x, cx.y, 8, cy.x + l.y, cy.y, 8);
  barrier();
  for (uint stride = 32u; stride > 0u; stride >>= 1u) {
    if (t < stride) partial[t] += partial[t + stride];
    barrier();
  }
  if (t != 0u) return;
  finish(cx, cy, partial[0]);
  imageStore(u_out0, m, o_image);
  imageStore(u_out1, m, uvec4(o_slot, 0u, 0u, 0u));
  imageStore(u_out2, m, vec4(o_depth, 0.0, 0.0, 0.0));
}
)";

// 2, 7. One point per map pixel of an object, added into a per-object table (the GPU histogram):
// mode 0 its pixel count, mode 1 (1, S_p, x, y) into its band of map rows, mode 2 one count into the
// radix select's bin of its depth (u_shift: the bits below the digit).
inline constexpr const char* kScatterVertex = R"(
uniform usampler2D u_slots, u_select;
uniform sampler2D u_saliency, u_map_depth;
uniform int u_n, u_mode, u_shift;
uniform ivec2 u_target;
flat out vec4 v_value;
void main() {
  ivec2 p = ivec2(gl_VertexID % u_n, gl_VertexID / u_n);
  uint slot1 = texelFetch(u_slots, p, 0).r;
  gl_Position = vec4(2.0, 2.0, 0.0, 1.0);  // outside the viewport: clipped
  v_value = vec4(1.0, 0.0, 0.0, 0.0);
  if (slot1 == 0u) return;
  int s = int(slot1) - 1;
  ivec2 t;
  if (u_mode == 0) {
    t = slot_texel(s);
  } else if (u_mode == 1) {
    t = ivec2((s & 63) * 16 + p.y * 16 / u_n, s >> 6);
    v_value = vec4(1.0, texelFetch(u_saliency, p, 0).r, (vec2(p) + 0.5) / float(u_n));
  } else {
    uvec2 st = texelFetch(u_select, slot_texel(s), 0).rg;
    uint key = sortable(texelFetch(u_map_depth, p, 0).r);
    if (key < st.x) return;
    uint bin = (key - st.x) >> uint(u_shift);
    if (bin >= 256u) return;
    t = ivec2((s & 3) * 256 + int(bin), s >> 2);
  }
  gl_Position = vec4((vec2(t) + 0.5) / vec2(u_target) * 2.0 - 1.0, 0.0, 1.0);
}
)";
inline constexpr const char* kScatterFragment = R"(#version 330 core
flat in vec4 v_value;
out vec4 o;
void main() { o = v_value; }
)";

// 3. The size and motion planes: each object's B_s (its pixels over the map's) and B_m.
inline constexpr const char* kPaint = R"(
uniform usampler2D u_slots;
uniform sampler2D u_counts, u_motion;
uniform float u_pixels;
void shade(ivec2 p) {
  uint slot1 = texelFetch(u_slots, p, 0).r;
  if (slot1 == 0u) { o = vec2(0.0); return; }
  ivec2 t = slot_texel(int(slot1) - 1);
  o = vec2(texelFetch(u_counts, t, 0).r / u_pixels, texelFetch(u_motion, t, 0).r);
}
)";

// 4. One pyramid level from the one below (feature_pyramid.cpp's downsample): 2x2 boxes, the rows
// clamped at the bottom edge, an odd width's last texel the mean of its two rows.
inline constexpr const char* kDown = R"(
uniform sampler2D u_image, u_object;
uniform ivec2 u_src;
vec4 down(sampler2D t, ivec2 d) {
  int y0 = min(2 * d.y, u_src.y - 1), y1 = min(2 * d.y + 1, u_src.y - 1), x0 = 2 * d.x;
  if (x0 + 1 < u_src.x) {
    return 0.25 * (texelFetch(t, ivec2(x0, y0), 0) + texelFetch(t, ivec2(x0 + 1, y0), 0) +
                   texelFetch(t, ivec2(x0, y1), 0) + texelFetch(t, ivec2(x0 + 1, y1), 0));
  }
  return 0.5 * (texelFetch(t, ivec2(u_src.x - 1, y0), 0) + texelFetch(t, ivec2(u_src.x - 1, y1), 0));
}
void shade(ivec2 d) {
  o_image = down(u_image, d);
  o_object = down(u_object, d).rg;
}
)";

// 5. Eq. 3.4 per feature, every level at the map pixel; coarse levels magnified as
// feature_pyramid.h's Magnified (texel centres, clamp to edge; along rows first, then between rows).
inline constexpr const char* kContrast = R"(
uniform sampler2D u_i0, u_i1, u_i2, u_i3, u_i4, u_i5, u_i6, u_o0, u_o1, u_o2, u_o3, u_o4, u_o5, u_o6;
uniform ivec2 u_dim[7];
uniform int u_n;
uniform bool u_image_group, u_object_group;
// Outputs: o_c0 (C_l, C_h, C_d, C_s), o_c1 (C_m).
vec4 magnified(sampler2D t, ivec2 m, ivec2 p) {
  vec2 s = (vec2(p) + 0.5) * vec2(m) / float(u_n) - 0.5;
  vec2 fl = floor(s), f = s - fl;
  ivec2 j = ivec2(fl);
  ivec2 i0 = clamp(j, ivec2(0), m - 1), i1 = clamp(j + 1, ivec2(0), m - 1);
  vec4 a = texelFetch(t, i0, 0), b = texelFetch(t, ivec2(i1.x, i0.y), 0);
  vec4 c = texelFetch(t, ivec2(i0.x, i1.y), 0), d = texelFetch(t, i1, 0);
  vec4 top = a + f.x * (b - a), bottom = c + f.x * (d - c);
  return top + f.y * (bottom - top);
}
float sane(float v) { return (isnan(v) || isinf(v) || v < 0.0) ? 0.0 : v; }
void shade(ivec2 p) {
  vec4 I[7], O[7];
  I[0] = texelFetch(u_i0, p, 0);
  O[0] = texelFetch(u_o0, p, 0);
  I[1] = magnified(u_i1, u_dim[1], p); O[1] = magnified(u_o1, u_dim[1], p);
  I[2] = magnified(u_i2, u_dim[2], p); O[2] = magnified(u_o2, u_dim[2], p);
  I[3] = magnified(u_i3, u_dim[3], p); O[3] = magnified(u_o3, u_dim[3], p);
  I[4] = magnified(u_i4, u_dim[4], p); O[4] = magnified(u_o4, u_dim[4], p);
  I[5] = magnified(u_i5, u_dim[5], p); O[5] = magnified(u_o5, u_dim[5], p);
  I[6] = magnified(u_i6, u_dim[6], p); O[6] = magnified(u_o6, u_dim[6], p);
  // The six (centre, surround) pairs of eq. 3.4: (0, 3), (0, 4), (1, 4), (1, 5), (2, 5), (2, 6).
  vec4 ci = abs(I[0] - I[3]) + abs(I[0] - I[4]) + abs(I[1] - I[4]) + abs(I[1] - I[5]) + abs(I[2] - I[5]) +
            abs(I[2] - I[6]);
  vec4 co = abs(O[0] - O[3]) + abs(O[0] - O[4]) + abs(O[1] - O[4]) + abs(O[1] - O[5]) + abs(O[2] - O[5]) +
            abs(O[2] - O[6]);
  float hue = distance(I[0].gb, I[3].gb) + distance(I[0].gb, I[4].gb) + distance(I[1].gb, I[4].gb) +
              distance(I[1].gb, I[5].gb) + distance(I[2].gb, I[5].gb) + distance(I[2].gb, I[6].gb);
  const float sixth = 1.0 / 6.0;
  float l = u_image_group ? sane(ci.r * sixth) : 0.0, h = u_image_group ? sane(hue * sixth) : 0.0;
  float d = u_object_group ? sane(ci.a * sixth) : 0.0, s = u_object_group ? sane(co.r * sixth) : 0.0;
  float m = u_object_group ? sane(co.g * sixth) : 0.0;
  o_c0 = vec4(l, h, d, s);
  o_c1 = vec4(m, 0.0, 0.0, 0.0);
}
)";

// 6. The largest value per channel of 8x8 blocks of two images (run until one texel is left).
inline constexpr const char* kReduce = R"(
uniform sampler2D u_in0, u_in1;
uniform ivec2 u_src;
void shade(ivec2 p) {
  ivec2 b = p * 8, e = min(b + 8, u_src);
  vec4 m0 = texelFetch(u_in0, b, 0), m1 = texelFetch(u_in1, b, 0);
  for (int y = b.y; y < e.y; ++y)
    for (int x = b.x; x < e.x; ++x) {
      m0 = max(m0, texelFetch(u_in0, ivec2(x, y), 0));
      m1 = max(m1, texelFetch(u_in1, ivec2(x, y), 0));
    }
  o0 = m0;
  o1 = m1;
}
)";

// 6. Eqs. 3.5-3.6 before the normalisation: sum w_f C_f with w_f = 1 / max C_f (a map without
// contrast contributes nothing); stored with its negation, so one max reduction finds its range.
inline constexpr const char* kWeigh = R"(
uniform sampler2D u_c0, u_c1, u_max0, u_max1;
void shade(ivec2 p) {
  vec4 c0 = texelFetch(u_c0, p, 0), m0 = texelFetch(u_max0, ivec2(0), 0);
  float c1 = texelFetch(u_c1, p, 0).r, m1 = texelFetch(u_max1, ivec2(0), 0).r;
  float sb = 0.0;
  if (m0.r > 0.0) sb += (1.0 / m0.r) * c0.r;
  if (m0.g > 0.0) sb += (1.0 / m0.g) * c0.g;
  if (m0.b > 0.0) sb += (1.0 / m0.b) * c0.b;
  if (m0.a > 0.0) sb += (1.0 / m0.a) * c0.a;
  if (m1 > 0.0) sb += (1.0 / m1) * c1;
  o = vec4(sb, -sb, 0.0, 0.0);
}
)";

// 6. S_p in [0, 1] by the weighted sum's range; an image whose pixels are all equal has no salient
// pixel (0); with neither feature group every pixel counts alike (1).
inline constexpr const char* kNormalise = R"(
uniform sampler2D u_weighted, u_range;
uniform bool u_all_off;
void shade(ivec2 p) {
  if (u_all_off) { o = 1.0; return; }
  vec2 r = texelFetch(u_range, ivec2(0), 0).rg;
  float hi = r.x, lo = -r.y, span = hi - lo;
  float sb = texelFetch(u_weighted, p, 0).r;
  o = span > 1e-6 * max(1.0, hi) ? clamp((sb - lo) * (1.0 / span), 0.0, 1.0) : 0.0;
}
)";

// 7. The radix select of each object's median depth: (the key's digits found so far, the rank
// still to find among the keys that share them), the rank starting at count / 2 (attention.cpp
// takes the element at n / 2 of the sorted depths).
inline constexpr const char* kSelectInit = R"(
uniform sampler2D u_counts;
void shade(ivec2 p) { o = uvec4(0u, uint(texelFetch(u_counts, p, 0).r) / 2u, 0u, 0u); }
)";
inline constexpr const char* kSelect = R"(
uniform usampler2D u_select;
uniform sampler2D u_histogram;
uniform int u_shift, u_objects_count;
void shade(ivec2 q) {
  int s = q.x + (q.y << 10);
  uvec2 st = texelFetch(u_select, q, 0).rg;
  o = uvec4(st, 0u, 0u);
  if (s >= u_objects_count) return;
  ivec2 row = ivec2((s & 3) * 256, s >> 2);
  uint before = 0u;
  for (int b = 0; b < 256; ++b) {
    uint c = uint(texelFetch(u_histogram, row + ivec2(b, 0), 0).r);
    if (before + c > st.y) {
      o = uvec4(st.x + (uint(b) << uint(u_shift)), st.y - before, 0u, 0u);
      return;
    }
    before += c;
  }
}
)";

}  // namespace fovea::render::gl_attention_glsl
