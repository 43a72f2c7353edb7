// vtkvol adaptive sampling (seed 000 §5.1.2; docs/rendering.md, vtkvol/engine/adaptive_sampling.py).
// Injected by the host for RenderSettings.adaptive_sampling (one channel, composite blend).
// Where the sample lies in a brick whose TF opacity is smooth (vv_asCoarse = 1) and the ray's
// next VV_AS_FACTOR − 1 steps stay inside that brick, the sample stands for VV_AS_FACTOR steps:
// its opacity is corrected for the longer segment, 1 − (1 − α)^k, and the ray moves on by k
// steps in all (k − 1 additions after compositing, VTK's loop makes the last one and runs its
// own termination tests). Elsewhere every step is taken, as without.
// Uniforms: sampler3D vv_asCoarse (R32F brick grid), vec3 vv_asTexDims (voxels x, y, z),
// vec3 vv_asBricks (bricks x, y, z). Defines: VV_AS_BRICK (vec3, voxels per brick x, y, z),
// VV_AS_FACTOR (float, steps per coarse sample).

//@inject //VTK::ComputeOpacity::Dec pre after
float vv_asSteps = 1.0;  // steps the current sample stands for
float vv_asOpacity(vec4 scalar)
{
  float a = computeOpacity(scalar);
  return vv_asSteps > 1.0 ? 1.0 - pow(max(1.0 - a, 0.0), vv_asSteps) : a;
}
#undef computeOpacity
#define computeOpacity vv_asOpacity

//@inject //VTK::PreComputeGradients::Impl pre before
vv_asSteps = 1.0;
if (!g_skip)
{
  ivec3 vv_asCell = ivec3(floor((g_dataPos * vv_asTexDims - 0.5) / VV_AS_BRICK));
  ivec3 vv_asEnd = ivec3(floor(((g_dataPos + g_dirStep * (VV_AS_FACTOR - 1.0)) * vv_asTexDims
                                - 0.5) / VV_AS_BRICK));
  // Both ends in one brick inside the grid (outside it nothing is coarse).
  if (all(equal(vv_asCell, vv_asEnd)) && all(greaterThanEqual(vv_asCell, ivec3(0)))
      && all(lessThan(vv_asCell, ivec3(vv_asBricks)))
      && texelFetch(vv_asCoarse, vv_asCell, 0).r > 0.0)
  {
    vv_asSteps = VV_AS_FACTOR;
  }
}

//@inject //VTK::RenderToImage::Impl pre before
// One addition per step, as VTK's loop makes them (host_empty_space.glsl says why).
for (float vv_asI = 1.0; vv_asI < vv_asSteps; vv_asI += 1.0)
{
  g_dataPos += g_dirStep;
}
g_currentT += vv_asSteps - 1.0;
