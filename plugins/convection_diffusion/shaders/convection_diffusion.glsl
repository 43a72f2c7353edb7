// vtkvol technique "convection_diffusion" (seed 003, KD): shading reads the light transported
// by plugins/convection_diffusion (compute shaders convection/march.comp.glsl, the engine's
// diffusion and tracker, numpy twin cpu.py) on the data's own grid, so texPos is the lookup
// coordinate. Lighting model: medium.
// Tested with VTK 9.7.1.
//
// Textures (bound by the host, retyped from int to sampler3D):
//   vv_convection_diffusion_direct     rho_l: light l's convected irradiance in channel l (0..1)
//   vv_convection_diffusion_scattered  rho_s: diffused (multiply scattered) light, rgb
//     on the data grid, or on the reduced grid of scatter_grid (⌈n/2⌉ or ⌈n/4⌉ texels per
//     axis tiling the same extent): either way sampled at texPos, like the data
//   vv_convection_diffusion_traced     the source model's traced scattering orders
//     E_1 + … + E_k (rgb, on the data grid; a 1³ zero texel without traced orders)

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)
{
  return texture(vv_convection_diffusion_direct, texPos)[light];
}

vec3 vv_irradiance(vec3 texPos)
{
  return texture(vv_convection_diffusion_scattered, texPos).rgb
    + texture(vv_convection_diffusion_traced, texPos).rgb;
}
