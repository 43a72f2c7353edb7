// vtkvol technique "hybrid_diffusion" (seed 003, HD): all of its light is irradiance on the
// data's grid (texPos is the lookup coordinate): the tracked direct light of every light
// combined, plus the diffused multiple scattering. Lighting model: medium (isotropic: the direct
// light of all lights shares one volume, so no phase function applies). Tested with VTK 9.7.1.
//
// Textures (bound by the host, retyped from int to sampler3D):
//   vv_hybrid_diffusion_direct     rho_d: running mean of the direct light (rgb)
//   vv_hybrid_diffusion_scattered  rho_s: diffused light (rgb)
//   vv_hybrid_diffusion_traced     the traced scattering orders E_1 + … + E_k (rgb; a zero texel
//     without traced orders), on the data grid
//     on the data grid, or on the reduced grid of scatter_grid (⌈n/2⌉ or ⌈n/4⌉ texels per
//     axis tiling the same extent): either way sampled at texPos, like the data

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS) { return 0.0; }

vec3 vv_irradiance(vec3 texPos)
{
  return texture(vv_hybrid_diffusion_direct, texPos).rgb
    + texture(vv_hybrid_diffusion_scattered, texPos).rgb
    + texture(vv_hybrid_diffusion_traced, texPos).rgb;
}
