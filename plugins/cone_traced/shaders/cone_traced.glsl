// vtkvol technique "cone_traced": soft shadows and ambient occlusion by cone tracing through a
// Gaussian-filtered opacity mip chain (seed 000's method 1, thesis §6.2, with its unit bug
// fixed). Python side: plugins/cone_traced/technique.py. Tested with VTK 9.7.1.
//
// Spaces: texPos = VTK's g_dataPos (0..1 over the data texture, voxel centres at (i+0.5)/N);
// the cone is marched in voxel space (index units), so the LOD rule and the steps are in voxels
// of the data grid also for anisotropic spacing; directions arrive in dataset space (µm) and are
// converted with VTK's texture–dataset matrix.
//
// Textures (bound by the host, retyped from int to sampler3D):
//   vv_cone_traced_filtered  D_L = -ln(1 - F_L): optical depth per opacity unit distance of the
//                            Gaussian-filtered mean opacity F_L of mip level L (border 0)
//   vv_cone_traced_opacity   TF opacity per unit distance (level 0 = the host's opacity volume)
//   vv_cone_traced_ao        baked AO (VV_CT_AO 3 only): occlusion 0..1 on the AO grid, which
//                            spans the data's point bounds (bake_ao.comp.glsl)
// Uniforms (custom, set by the host every frame):
//   vec3  vv_cone_traced_dims           data dimensions (x, y, z) voxels
//   float vv_cone_traced_maxLod         coarsest level
//   float vv_cone_traced_unit           opacity unit distance u, µm
//   float vv_cone_traced_sigma          filter σ, texels of each level
//   float vv_cone_traced_lod_width      the level rises while b·sin(angle) > lod_width·σ·2^L
//   float vv_cone_traced_h, _h0         level-0 step and start offset, voxels
//   float vv_cone_traced_shadowSin      sin(shadow cone half-angle)
//   float vv_cone_traced_aoSin          sin(view-cone AO half-angle)
//   float vv_cone_traced_maxDistanceUm  AO maximum distance, µm
//   vec3  vv_cone_traced_aoDims         baked-AO grid points (x, y, z)
//   float vv_cone_traced_shadow_strength, _ao_strength, _opacity_threshold
// Compile-time variants (llvmpipe: a branch on a uniform costs as much as all its branches):
//   VV_CT_SHADOWS 0|1, VV_CT_AO 0 off | 1 view cone | 2 hemisphere | 3 baked hemisphere,
//   VV_CT_AO_CONES,
//   VV_CT_AO_DIRS (cone axes in the normal's frame), VV_CT_AO_SIN, and for the march
//   (cone_march.glsl) VV_CONE_MAX_STEPS, VV_CONE_TAU_EXIT.
//
// Shading (host_lighting.glsl): ambient × A, diffuse and specular of light i × V_i, with
//   V_i = 1 - shadow_strength * (1 - T_cone(light i)),   A = 1 - ao_strength * AO,
// both 1 for samples whose TF opacity is at or below the threshold (baked AO: A applies to
// every sample; it is one trilinear fetch, cheaper than the gate).

//@inject //VTK::ComputeLighting::Dec pre before
const vec3 vv_ct_aoDirs[VV_CT_AO_CONES] = VV_CT_AO_DIRS;

//@include cone_march.glsl

// Transmittance (0..1] of one cone from texPos along the unit dataset-space direction dirDS.
float vv_ct_trace(vec3 texPos, vec3 dirDS, float sinAngle, float maxDistUm)
{
  vec3 dVox = vv_datasetDirToTex(dirDS) * vv_cone_traced_dims;  // voxels per µm, per axis
  return vv_cone_march(vv_cone_traced_filtered, texPos, dVox, vv_cone_traced_dims,
                       vv_cone_traced_unit, maxDistUm, sinAngle,
                       vv_cone_traced_lod_width * vv_cone_traced_sigma, vv_cone_traced_h,
                       vv_cone_traced_h0, vv_cone_traced_maxLod);
}

// The opacity gate, evaluated once per sample (the host asks AO first, then every light at the
// same g_dataPos).
vec3 vv_ct_gatePos = vec3(-1.0);
bool vv_ct_gateOpen = false;
bool vv_ct_active(vec3 texPos)
{
  if (texPos != vv_ct_gatePos)
  {
    vv_ct_gatePos = texPos;
    vv_ct_gateOpen =
      textureLod(vv_cone_traced_opacity, texPos, 0.0).r > vv_cone_traced_opacity_threshold;
  }
  return vv_ct_gateOpen;
}

float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
#if VV_CT_SHADOWS
  if (!vv_ct_active(texPos)) return 1.0;
  float maxUm = 1e30;  // directional light: until the cone leaves the volume
  if (vv_lightIsPoint(light))
  {
    maxUm = length(vv_lightVector(light) - vv_texToDataset(texPos));
  }
#if VV_CT_CONE_FROM_LIGHT
  // The cone the light subtends: its angular radius (directional) or radius / distance (point).
  float size = vv_lightSize(light);
  float sinAngle = vv_lightIsPoint(light) ? min(size / max(maxUm, 1e-6), 1.0) : sin(size);
#else
  float sinAngle = vv_cone_traced_shadowSin;
#endif
  float t = vv_ct_trace(texPos, dirDS, sinAngle, maxUm);
  return 1.0 - vv_cone_traced_shadow_strength * (1.0 - t);
#else
  return 1.0;
#endif
}

float vv_ambient_visibility(vec3 texPos, vec3 normalDS)
{
#if VV_CT_AO == 0
  return 1.0;
#elif VV_CT_AO == 3
  // Baked: the hemisphere about the opacity's outward normal, precomputed on the AO grid.
  vec3 tc = vv_unitToGrid(vv_texToUnit(texPos), vv_cone_traced_aoDims);
  return 1.0 - vv_cone_traced_ao_strength * textureLod(vv_cone_traced_ao, tc, 0.0).r;
#else
  if (!vv_ct_active(texPos)) return 1.0;
  vec3 toEye = normalize(in_eyePosObjs[0].xyz - vv_texToDataset(texPos));
  float occlusion = 0.0;
#if VV_CT_AO == 1
  occlusion = 1.0 - vv_ct_trace(texPos, toEye, vv_cone_traced_aoSin, vv_cone_traced_maxDistanceUm);
#else
  // Homogeneous regions have no normal: use the hemisphere facing the viewer there.
  vec3 n = dot(normalDS, normalDS) > 0.0 ? normalDS : toEye;
  // Orthonormal frame about n (Duff et al. 2017, branchless).
  float sgn = n.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (sgn + n.z);
  float bb = n.x * n.y * a;
  vec3 t = vec3(1.0 + sgn * n.x * n.x * a, sgn * bb, -sgn * n.x);
  vec3 bt = vec3(bb, sgn + n.y * n.y * a, -n.y);
  for (int k = 0; k < VV_CT_AO_CONES; ++k)
  {
    vec3 d = vv_ct_aoDirs[k];
    occlusion += 1.0 - vv_ct_trace(texPos, d.x * t + d.y * bt + d.z * n, VV_CT_AO_SIN,
                                   vv_cone_traced_maxDistanceUm);
  }
  occlusion /= float(VV_CT_AO_CONES);
#endif
  return 1.0 - vv_cone_traced_ao_strength * occlusion;
#endif
}
