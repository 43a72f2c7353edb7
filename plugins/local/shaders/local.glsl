// vtkvol technique "local": local (Blinn–Phong) shading with the scene's lights, no shadows
// and no occlusion. The baseline every other technique is timed and compared against.
// Tested with VTK 9.7.1. Uniforms: none of its own.

//@inject //VTK::ComputeLighting::Dec pre before
float vv_light_visibility(int light, vec3 texPos, vec3 dirDS) { return 1.0; }
float vv_ambient_visibility(vec3 texPos, vec3 normalDS) { return 1.0; }
