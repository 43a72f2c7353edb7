// vtkvol host defaults for the technique hooks (docs/architecture.md, "Technique contract").
// Injected after the technique's code and before the lighting model. A technique defines only
// the hooks it changes; the host finds them in its GLSL and defines VV_HAS_<HOOK> for each, so
// the defaults below stand for the rest. Tested with VTK 9.7.1.
//
//   float vv_light_visibility(int light, vec3 texPos, vec3 dirDS)         1 = unshadowed
//   vec3  vv_light_transmittance_rgb(int light, vec3 texPos, vec3 dirDS)  coloured; default:
//                                                                        the scalar visibility
//   float vv_ambient_visibility(vec3 texPos, vec3 normalDS)              1 = unoccluded
//   vec3  vv_irradiance(vec3 texPos)       in-scattered light (radiance units of the light
//                                          colour, isotropic); default 0
// texPos: VTK's texture coordinate g_dataPos; directions: unit, dataset space.

//@inject //VTK::ComputeLighting::Dec pre before
#ifndef VV_HAS_LIGHT_VISIBILITY
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS) { return 1.0; }
#endif
#ifndef VV_HAS_LIGHT_TRANSMITTANCE_RGB
vec3 vv_light_transmittance_rgb(int light, vec3 texPos, vec3 dirDS)
{
  return vec3(vv_light_visibility(light, texPos, dirDS));
}
#endif
#ifndef VV_HAS_AMBIENT_VISIBILITY
float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
#endif
#ifndef VV_HAS_IRRADIANCE
vec3 vv_irradiance(vec3 texPos) { return vec3(0.0); }
#endif
