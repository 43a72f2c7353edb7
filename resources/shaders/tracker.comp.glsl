#version 430
// vtkvol engine: per-voxel tracking towards the lights, shared by the grid-diffusion techniques
// (hybrid_diffusion's direct light, both techniques' traced scattering orders; driver
// vtkvol/engine/traced_orders.py:GpuTracker). In place: each invocation touches only its own
// voxel of the running means. The direct light mirrors plugins/hybrid_diffusion/cpu.py
// operation by operation in float32 (the numpy path is the test oracle). Tested with VTK 9.7.1
// on Mesa llvmpipe (GL 4.5).
//
// Defines: VV_DIRECT (1 = one sample of the direct light per voxel averaged into the running
// mean vv_direct, hybrid_diffusion; 0 = no direct light and no vv_direct image, only the traced
// orders, convection_diffusion, which ray-marches its direct light), VV_RATIO (1 = ratio
// tracking, 0 = delta tracking), VV_ALL_LIGHTS (1 = every light per iteration, 0 = one chosen at
// random), VV_MAX_STEPS, VV_MIN_THROUGHPUT, VV_BRICKS (1 = the per-brick majorant grid
// vv_bricks, bricks of VV_BRICK voxels; 0 = the global vv_majorant).
// VV_ORDERS k > 0 (source model, `traced_orders`): one path per voxel also traces the first k
// scattering orders (delta tracking to each collision, next-event estimation by the same
// tracker), averaged into vv_traced (E_1 + … + E_k) and vv_last (E_k, the diffusion's source);
// its numpy counterpart is the Monte-Carlo reference (vtkvol.reference.inscattered_mc through
// vtkvol.engine.traced_orders.traced_orders_sample, the same estimator with other random
// numbers: compared statistically). VV_DIRECT 0 needs VV_ORDERS > 0.
// Image units: 0 vv_sigma, 1 vv_direct, 2 vv_bricks, 3 vv_traced, 4 vv_last.
// Grid: the data's voxel centres (dataset µm: vv_origin + vv_spacing * index).

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(r32f) uniform readonly image3D vv_sigma;        // extinction sigma_t per µm
#if VV_DIRECT
layout(rgba32f) uniform image3D vv_direct;             // rho_d (rgb), read and written
#elif VV_ORDERS <= 0
#error "VV_DIRECT 0 traces only the scattering orders: VV_ORDERS must be > 0"
#endif
uniform ivec3 vv_dims;
#if VV_BRICKS
layout(r32f) uniform readonly image3D vv_bricks;       // majorant per brick (per µm)
uniform ivec3 vv_brickDims;
#endif
uniform ivec2 vv_first;         // the region drawn: vv_first <= (z, y) < vv_end (bounded
uniform ivec2 vv_end;           // chunks: one sample drawn in z slabs and y bands)
uniform vec3 vv_origin;
uniform vec3 vv_spacing;
uniform float vv_majorant;      // max sigma_t (per µm)
uniform float vv_unitDistance;  // µm: > 0 samples the extinction of the interpolated opacity
                                // 1 - exp(-sigma_t u) (cpu.py's extinction_at); 0: sigma_t
uniform uint vv_iteration;      // k: the running mean's sample index
uniform uint vv_seed;
uniform int vv_numLights;
uniform vec4 vv_lightVec[4];    // xyz: direction towards the light (unit) or position; w = point
uniform vec3 vv_color[4];
uniform float vv_lightSize[4];  // angular radius (rad, directional) or sphere radius (µm, point)
uniform vec4 vv_falloff[4];     // position (µm) and d0 (µm; 0 = none): irradiance * (d0/r)^2
#if VV_ORDERS > 0
layout(rgba32f) uniform image3D vv_traced;             // E_1 + … + E_k (rgb), read and written
layout(rgba32f) uniform image3D vv_last;               // E_k (rgb), read and written
uniform float vv_albedo;        // single-scattering albedo a
uniform float vv_phaseG;        // Henyey–Greenstein asymmetry g
#endif

uint pcg(uint v)
{
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// Inverse-square fall-off of light l at pos (1 without), as the host's vv_lightColor.
float falloffAt(int l, vec3 pos)
{
  if (vv_falloff[l].w <= 0.0) return 1.0;
  vec3 r = pos - vv_falloff[l].xyz;
  return vv_falloff[l].w * vv_falloff[l].w / max(dot(r, r), 1e-12);
}

float uniformDraw(uint key, uint draw)
{
  return float(pcg(key + draw) >> 8u) * (1.0 / 16777216.0);
}

//@include grid_cell.glsl

float lerp(float a, float b, float w) { return a * (1.0 - w) + b * w; }

// What is interpolated at a voxel: sigma_t, or with vv_unitDistance > 0 the opacity of one
// unit distance (as the ray caster and the exact reference sample the data).
float cornerAt(ivec3 i)
{
  float s = imageLoad(vv_sigma, i).r;
  return vv_unitDistance > 0.0 ? 1.0 - exp(-s * vv_unitDistance) : s;
}

float sigmaAt(vec3 p)
{
  ivec3 i0, i1;
  vec3 w;
  vv_gridCell(p, i0, i1, w);
  float c00 = lerp(cornerAt(ivec3(i0.x, i0.y, i0.z)), cornerAt(ivec3(i1.x, i0.y, i0.z)), w.x);
  float c01 = lerp(cornerAt(ivec3(i0.x, i1.y, i0.z)), cornerAt(ivec3(i1.x, i1.y, i0.z)), w.x);
  float c10 = lerp(cornerAt(ivec3(i0.x, i0.y, i1.z)), cornerAt(ivec3(i1.x, i0.y, i1.z)), w.x);
  float c11 = lerp(cornerAt(ivec3(i0.x, i1.y, i1.z)), cornerAt(ivec3(i1.x, i1.y, i1.z)), w.x);
  float v = lerp(lerp(c00, c01, w.y), lerp(c10, c11, w.y), w.z);
  if (vv_unitDistance <= 0.0) return v;
  return -log(1.0 - min(v, 1.0 - 1e-6)) / vv_unitDistance;
}

#if VV_BRICKS
// (majorant, distance in µm to the brick's exit along d) of the brick holding p, looked up a
// thousandth of the smallest voxel edge further along d (a point on a face belongs to the
// brick the path enters) — cpu.py's _brick_step.
vec2 brickAt(vec3 p, vec3 d)
{
  float h = min(vv_spacing.x, min(vv_spacing.y, vv_spacing.z));
  ivec3 b;
  float exitT = 1e30;
  for (int a = 0; a < 3; ++a)
  {
    float v = (p[a] - vv_origin[a]) / vv_spacing[a] + 1e-3 * d[a] / vv_spacing[a] * h;
    b[a] = clamp(int(floor(v / float(VV_BRICK))), 0, vv_brickDims[a] - 1);
    float lo = vv_origin[a] + vv_spacing[a] * float(b[a] * VV_BRICK);
    float hi = vv_origin[a] + vv_spacing[a] * float(min((b[a] + 1) * VV_BRICK, vv_dims[a] - 1));
    float t = d[a] > 0.0 ? (hi - p[a]) / d[a] : (d[a] < 0.0 ? (lo - p[a]) / d[a] : 1e30);
    exitT = min(exitT, max(t, 0.0));
  }
  return vec2(imageLoad(vv_bricks, b).r, exitT);
}
#endif

// Unit vector at cosine c and azimuth phi about the unit vector w (as the numpy twin's).
vec3 around(vec3 w, float c, float phi)
{
  float s = sqrt(max(0.0, 1.0 - c * c));
  vec3 a = abs(w.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 t1 = normalize(cross(w, a));
  vec3 t2 = cross(w, t1);
  return normalize(s * cos(phi) * t1 + s * sin(phi) * t2 + c * w);
}

// One tentative collision of a flight from pos along the unit d, from the distance t (µm) on
// with the uniform number xi: t advances to it and the result is the probability that it is
// real, σ/majorant there (0 when, with bricks, the flight stopped at its brick's face without
// an event: the exponential flight is memoryless; an empty brick is crossed in one step). The
// caller checks t against the end of its ray before using the result.
float tentativeCollision(vec3 pos, vec3 d, float xi, inout float t)
{
#if VV_BRICKS
  float minStep = 1e-4 * min(vv_spacing.x, min(vv_spacing.y, vv_spacing.z));
  vec2 brick = brickAt(pos + t * d, d);
  float local = brick.x;
  float toFace = max(brick.y, minStep);
  float freeFlight = local > 0.0 ? -log(1.0 - xi) / local : 1e30;
  bool event = freeFlight < toFace;
  t = t + (event ? freeFlight : toFace);
  return event ? min(sigmaAt(pos + t * d) / max(local, 1e-30), 1.0) : 0.0;
#else
  float invMajorant = 1.0 / vv_majorant;
  t = t - log(1.0 - xi) * invMajorant;
  return min(sigmaAt(pos + t * d) * invMajorant, 1.0);
#endif
}

// Throughput from pos towards light l (draws start at firstDraw). A sized light is sampled
// per path: a point on its sphere, or a direction in its cone (draws firstDraw + 4094, 4095).
float track(uint key, vec3 pos, int l, uint firstDraw)
{
  vec3 d;
  float dist = 1e30;
  float size = vv_lightSize[l];
  float u1 = uniformDraw(key, firstDraw + 4094u);
  float u2 = uniformDraw(key, firstDraw + 4095u);
  if (vv_lightVec[l].w > 0.5)
  {
    vec3 target = vv_lightVec[l].xyz;
    if (size > 0.0) target += size * around(vec3(0.0, 0.0, 1.0), 1.0 - 2.0 * u1, 6.2831853 * u2);
    d = target - pos;
    dist = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    d = d * (1.0 / max(dist, 1e-12));
  }
  else
  {
    d = vv_lightVec[l].xyz;
    if (size > 0.0) d = around(d, 1.0 - u1 * (1.0 - cos(size)), 6.2831853 * u2);
  }
  float tEnd = min(vv_boxExit(pos, d), dist);
  if (vv_majorant <= 0.0) return 1.0;
  float throughput = 1.0;
  float t = 0.0;
  uint draw = firstDraw;
  for (int step = 0; step < VV_MAX_STEPS; ++step)
  {
    float xi = uniformDraw(key, draw);
    draw += 1u;
    float ratio = tentativeCollision(pos, d, xi, t);
    if (t >= tEnd) return throughput;
#if VV_RATIO
    throughput = throughput * (1.0 - ratio);
    if (throughput < VV_MIN_THROUGHPUT) return throughput;
#else
    if (uniformDraw(key, draw) < ratio) return 0.0;
#endif
    draw += 1u;
  }
  return 0.0;  // too many tentative collisions: absorbed
}

#if VV_ORDERS > 0
// Delta tracking from pos along the unit d: true and the distance tHit (µm) of the first real
// collision, false when the path leaves the box first (draws from firstDraw on, two a step).
bool collide(uint key, vec3 pos, vec3 d, uint firstDraw, out float tHit)
{
  tHit = 0.0;
  float tEnd = vv_boxExit(pos, d);
  if (vv_majorant <= 0.0) return false;
  float t = 0.0;
  uint draw = firstDraw;
  for (int step = 0; step < VV_MAX_STEPS; ++step)
  {
    float ratio = tentativeCollision(pos, d, uniformDraw(key, draw), t);
    if (t >= tEnd) return false;
    if (uniformDraw(key, draw + 1u) < ratio)
    {
      tHit = t;
      return true;
    }
    draw += 2u;
  }
  return false;  // too many tentative collisions: the path is dropped
}

// 4π × the Henyey–Greenstein phase function at scattering cosine mu (1 when g = 0).
float phase4pi(float mu)
{
  float g = vv_phaseG;
  return (1.0 - g * g) / pow(max(1.0 + g * g - 2.0 * g * mu, 1e-12), 1.5);
}

// A direction drawn from the Henyey–Greenstein phase function about the unit w.
vec3 sampleHG(vec3 w, float u1, float u2)
{
  float g = vv_phaseG;
  float c;
  if (abs(g) < 1e-3)
  {
    c = 1.0 - 2.0 * u1;
  }
  else
  {
    float s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
    c = clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0);
  }
  return around(w, c, 6.2831853 * u2);
}

// Orders 1 … VV_ORDERS of the light arriving at pos from one path: (E_1 + … + E_k, E_k), rgb.
// The path leaves pos in a uniform direction, then in directions drawn from the phase
// function; at each collision every light is reached by the tracker (next-event estimation),
// weighted by the albedo per collision and 4π p_g of the angle the light turns there.
void tracedOrders(uint key, vec3 pos, out vec3 traced, out vec3 last)
{
  traced = vec3(0.0);
  last = vec3(0.0);
  vec3 x = pos;
  vec3 dir = vec3(0.0, 0.0, 1.0);
  float weight = 1.0;
  for (int k = 1; k <= VV_ORDERS; ++k)
  {
    uint base = uint(k) * 65536u;
    float u1 = uniformDraw(key, base);
    float u2 = uniformDraw(key, base + 1u);
    dir = k == 1 ? around(vec3(0.0, 0.0, 1.0), 1.0 - 2.0 * u1, 6.2831853 * u2)
                 : sampleHG(dir, u1, u2);
    float t;
    if (!collide(key, x, dir, base + 2u, t)) return;
    x = x + t * dir;
    weight *= vv_albedo;
    vec3 e = vec3(0.0);
    for (int l = 0; l < vv_numLights; ++l)
    {
      vec3 towards = vv_lightVec[l].w > 0.5 ? normalize(vv_lightVec[l].xyz - x) : vv_lightVec[l].xyz;
      float p = phase4pi(dot(towards, dir));
      e += (track(key, x, l, base + 4096u * uint(l + 1)) * falloffAt(l, x) * p) * vv_color[l];
    }
    traced += weight * e;
    if (k == VV_ORDERS) last = weight * e;
  }
}
#endif

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID) + ivec3(0, vv_first.y, vv_first.x);
  if (any(greaterThanEqual(p, vv_dims)) || p.z >= vv_end.x || p.y >= vv_end.y) return;
  uint index = uint(p.x + vv_dims.x * (p.y + vv_dims.y * p.z));
  uint key = pcg(index ^ pcg(vv_iteration + pcg(vv_seed)));
  vec3 pos = vv_origin + vv_spacing * vec3(p);
#if VV_DIRECT
  vec3 sampleRGB = vec3(0.0);
#if VV_ALL_LIGHTS
  for (int l = 0; l < vv_numLights; ++l)
  {
    sampleRGB += (track(key, pos, l, 1u + 4096u * uint(l)) * 1.0 * falloffAt(l, pos)) * vv_color[l];
  }
#else
  if (vv_numLights > 0)
  {
    int l = min(int(uniformDraw(key, 0u) * float(vv_numLights)), vv_numLights - 1);
    sampleRGB = (track(key, pos, l, 1u + 4096u * uint(l)) * float(vv_numLights) * falloffAt(l, pos))
      * vv_color[l];
  }
#endif
  vec3 mean = imageLoad(vv_direct, p).rgb;
  mean = mean + (sampleRGB - mean) / float(vv_iteration + 1u);
  imageStore(vv_direct, p, vec4(mean, 0.0));
#endif
#if VV_ORDERS > 0
  // Only where a visible sample can read it: a voxel whose 26 neighbours are all empty is a
  // corner of no cell with opacity, so its traced light is never shown (nor a source of the
  // diffusion, which has no unknown there); it stays 0 and costs no path.
  bool readable = false;
  for (int dz = -1; dz <= 1 && !readable; ++dz)
    for (int dy = -1; dy <= 1 && !readable; ++dy)
      for (int dx = -1; dx <= 1 && !readable; ++dx)
      {
        ivec3 n = clamp(p + ivec3(dx, dy, dz), ivec3(0), vv_dims - 1);
        readable = imageLoad(vv_sigma, n).r > 0.0;
      }
  if (!readable) return;
  vec3 traced, last;
  tracedOrders(pcg(key ^ 0x68bc21ebu), pos, traced, last);
  float w = 1.0 / float(vv_iteration + 1u);
  vec3 tracedMean = imageLoad(vv_traced, p).rgb;
  vec3 lastMean = imageLoad(vv_last, p).rgb;
  imageStore(vv_traced, p, vec4(tracedMean + (traced - tracedMean) * w, 0.0));
  imageStore(vv_last, p, vec4(lastMean + (last - lastMean) * w, 0.0));
#endif
}
