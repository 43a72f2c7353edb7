// vtkvol engine: the trilinear cell of a point on a grid of voxel centres, clamped to the box
// (clamp-to-edge sampling, as VTK's textures and the numpy twins sample), for compute shaders
// that interpolate an image3D by hand (image loads do not filter), and the distance to that box's
// exit along a ray. Shared by
// convection_diffusion's march.comp.glsl and the engine's tracker.comp.glsl. The
// including shader declares vv_dims (voxels), vv_origin and vv_spacing (µm).

// Corners i0, i1 (voxel indices, i1 = i0 + 1 inside the box) and weights w of p (µm).
void vv_gridCell(vec3 p, out ivec3 i0, out ivec3 i1, out vec3 w)
{
  for (int a = 0; a < 3; ++a)
  {
    float f = clamp((p[a] - vv_origin[a]) / vv_spacing[a], 0.0, float(vv_dims[a] - 1));
    i0[a] = int(min(floor(f), float(max(vv_dims[a] - 2, 0))));
    i1[a] = min(i0[a] + 1, vv_dims[a] - 1);
    w[a] = f - float(i0[a]);
  }
}

// Distance (µm, ≥ 0) from p along the unit d to the exit of the box of voxel centres.
float vv_boxExit(vec3 p, vec3 d)
{
  float exitT = 1e30;
  for (int a = 0; a < 3; ++a)
  {
    float lo = vv_origin[a];
    float hi = vv_origin[a] + vv_spacing[a] * float(vv_dims[a] - 1);
    float t = d[a] > 0.0 ? (hi - p[a]) / d[a] : (d[a] < 0.0 ? (lo - p[a]) / d[a] : 1e30);
    exitT = min(exitT, t);
  }
  return max(exitT, 0.0);
}
