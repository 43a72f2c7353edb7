#version 430
// vtkvol engine: one Jacobi sweep of the "source" diffusion model (vtkvol/engine/diffusion.py,
// jacobi_sweep and source_term, operation by operation; the numpy path is the test oracle):
//   -div(D grad phi) + sigma_a phi = sigma_s E_0,  E_0 = sum_l colour_l * falloff_l * direct_l.
// Cell-centred finite volumes; harmonic mean of D between medium voxels; a Marshak vacuum face
// (outflow phi / (2 + h / (2 D))) towards empty voxels and the box. D = 0 marks an empty voxel;
// one next to the medium shows the mean phi of its medium neighbours.
// Tested with VTK 9.7.1 on Mesa llvmpipe (GL 4.5).
//
// Defines: VV_CHANNELS 1, 2 or 4 (lights in vv_direct); VV_SOURCE_IMAGE 1: q is read from
// vv_source (rgb, per um^3; the reduced grid's restricted source, source_restrict.comp.glsl)
// instead of being computed from vv_direct on this grid.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

//@include light_format.glsl

#if VV_SOURCE_IMAGE
layout(rgba32f) uniform readonly image3D vv_source;        // q (rgb) per point of this grid
#else
layout(VV_FORMAT) uniform readonly image3D vv_direct;      // direct light l in channel l
#endif
layout(rgba32f) uniform readonly image3D vv_coefficients;  // (D um, sigma_a, sigma_s, 0) per um
layout(rgba32f) uniform readonly image3D vv_phiIn;         // phi (rgb)
layout(rgba32f) uniform writeonly image3D vv_phiOut;
layout(rg32f) uniform writeonly image3D vv_residual;       // (|b - A phi|^2, |b|^2) per voxel
uniform ivec3 vv_dims;
uniform int vv_zFirst;          // first z layer of this dispatch (a sweep in z slabs)
uniform vec3 vv_spacing;        // um
uniform vec3 vv_origin;         // um, first voxel centre
uniform int vv_numLights;
uniform vec3 vv_color[4];       // colour * intensity of each light
uniform vec4 vv_falloff[4];     // position (um) and d0 (um; 0 = no fall-off) of each light

//@include direct_irradiance.glsl

bool outside(ivec3 p) { return any(lessThan(p, ivec3(0))) || any(greaterThanEqual(p, vv_dims)); }

void main()
{
  ivec3 p = ivec3(gl_GlobalInvocationID) + ivec3(0, 0, vv_zFirst);
  if (outside(p)) return;
  vec4 k = imageLoad(vv_coefficients, p);
  vec3 phi = imageLoad(vv_phiIn, p).rgb;
  float d = k.x;
  if (d <= 0.0)
  {
    // No unknown here. Next to the medium: the mean of the medium neighbours' phi (26-
    // neighbourhood; diffusion.py's surface_fill), so that the trilinear fetch at the
    // medium's surface does not blend towards 0; elsewhere 0.
    vec3 acc = vec3(0.0);
    float count = 0.0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
        {
          ivec3 n = p + ivec3(dx, dy, dz);
          if ((dx == 0 && dy == 0 && dz == 0) || outside(n)) continue;
          if (imageLoad(vv_coefficients, n).x > 0.0)
          {
            acc += imageLoad(vv_phiIn, n).rgb;
            count += 1.0;
          }
        }
    imageStore(vv_phiOut, p, vec4(count > 0.0 ? acc / max(count, 1.0) : vec3(0.0), 0.0));
    imageStore(vv_residual, p, vec4(0.0));
    return;
  }
#if VV_SOURCE_IMAGE
  vec3 q = imageLoad(vv_source, p).rgb;
#else
  vec4 rho = imageLoad(vv_direct, p);
  vec3 pos = vv_origin + vv_spacing * vec3(p);
  vec3 e0 = vv_directIrradiance(rho, pos);
  vec3 q = k.z * e0;
#endif
  float diag = k.y;
  vec3 acc = q;
  for (int a = 0; a < 3; ++a)
  {
    float h = vv_spacing[a];
    for (int s = -1; s <= 1; s += 2)
    {
      ivec3 n = p;
      n[a] += s;
      float dn = outside(n) ? 0.0 : imageLoad(vv_coefficients, n).x;
      if (dn > 0.0)
      {
        float cond = 2.0 * d * dn / (d + dn) / (h * h);
        diag += cond;
        acc += cond * imageLoad(vv_phiIn, n).rgb;
      }
      else
      {
        diag += 1.0 / (h * (2.0 + h / (2.0 * d)));
      }
    }
  }
  vec3 r = acc - diag * phi;
  imageStore(vv_phiOut, p, vec4(acc / diag, 0.0));
  imageStore(vv_residual, p, vec4(dot(r, r), dot(q, q), 0.0, 0.0));
}
