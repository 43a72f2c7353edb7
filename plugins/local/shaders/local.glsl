// vtkvol technique "local": local (Blinn–Phong) shading with the scene's lights, no shadows
// and no occlusion. The baseline every other technique is timed and compared against.
// It defines no hook: the host's defaults (resources/shaders/host_hooks.glsl: every light
// fully visible, no occlusion, no in-scattering) are exactly local shading.
