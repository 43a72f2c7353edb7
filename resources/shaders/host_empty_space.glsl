// vtkvol empty-space skipping (seed 001 §2.4, seed 000 §5.1.3; docs/empty-space-skipping.md).
// Injected by the host at the top of VTK's per-sample loop, after `g_skip = false` and before
// cropping, the fetch and every technique's lighting.
//
// The occupancy grid (vtkvol.engine.occupancy) marks bricks of VV_ESS_BRICK voxels (a vec3:
// x, y, z; near cubes in µm) in which
// no sample can have a non-zero opacity (transfer function, crop and slice weights; every
// trilinear sample in a brick reads only the brick and its apron). When the current sample
// lies in such a brick, every sample up to the brick's far face is zero too: the ray moves on
// by a whole number k of steps, so it stays on VTK's own sample lattice
// (g_rayOrigin + n·g_dirStep, jitter included) and the samples it still takes are exactly the
// ones it took without skipping. It moves k − 1 steps here and marks the sample it lands on
// (still inside the empty brick) g_skip; VTK's loop then makes the last step and runs its own
// termination test (past the texture's bounds, or past g_terminatePointMax: the depth buffer
// and clipping planes), which, bounds and T being monotone along the ray, is the test it would
// have run on every skipped sample. g_currentT advances with the ray.
// Leading, trailing and interior empty space are all skipped, one brick per loop iteration.
//
// Uniforms (custom, set by the host):
//   sampler3D vv_essOccupancy   R32F brick grid, 1 = may contribute, 0 = empty; texelFetch
//   vec3      vv_essTexDims     voxels of the data texture (x, y, z)
//   vec3      vv_essBricks      bricks per axis (x, y, z)

//@inject //VTK::Base::Impl pre after
{
  // Voxel coordinates: voxel centres at integers (texture (i + 0.5)/N ↔ voxel i).
  vec3 vv_essVoxel = g_dataPos * vv_essTexDims - 0.5;
  ivec3 vv_essLast = ivec3(vv_essBricks) - 1;
  ivec3 vv_essCell = clamp(ivec3(floor(vv_essVoxel / VV_ESS_BRICK)), ivec3(0), vv_essLast);
  if (texelFetch(vv_essOccupancy, vv_essCell, 0).r == 0.0)
  {
    // The brick's box in voxel coordinates; the outermost bricks reach past the texture
    // (their samples there clamp to the face voxels, which the brick's range includes).
    vec3 vv_essLo = vec3(vv_essCell) * VV_ESS_BRICK;
    vec3 vv_essHi = vv_essLo + VV_ESS_BRICK;
    vv_essLo = mix(vv_essLo, vec3(-2.0), equal(vv_essCell, ivec3(0)));
    vv_essHi = mix(vv_essHi, vv_essTexDims + 1.0, equal(vv_essCell, vv_essLast));
    vec3 vv_essStep = g_dirStep * vv_essTexDims;  // voxels per step
    vec3 vv_essFace = mix(vv_essLo, vv_essHi, greaterThan(vv_essStep, vec3(0.0)));
    vec3 vv_essMoving = vec3(greaterThan(abs(vv_essStep), vec3(1e-12)));
    // Steps to the far face per axis (never reached along an axis the ray does not move on).
    vec3 vv_essT = mix(vec3(1e30),
                       (vv_essFace - vv_essVoxel) / (vv_essStep + (1.0 - vv_essMoving)),
                       vv_essMoving);
    float vv_essExit = min(min(vv_essT.x, vv_essT.y), vv_essT.z);
    // Samples strictly inside the brick are zero; the margin keeps a sample rounding puts on
    // the face (it is simply taken, as without skipping).
    float vv_essJump = max(1.0, ceil(vv_essExit - 1e-3));
    // One addition per step, as VTK's loop makes them: the samples after the jump sit at
    // bit-identical positions (a single multiply-add rounds differently, and at a sharp edge a
    // 1e-5 texel shift is visible).
    for (float vv_essI = 1.0; vv_essI < vv_essJump; vv_essI += 1.0)
    {
      g_dataPos += g_dirStep;
    }
    g_currentT += vv_essJump - 1.0;
    g_skip = true;
  }
}
