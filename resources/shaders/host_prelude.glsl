// vtkvol host prelude: coordinate helpers and light uniforms shared by every technique.
// Injected by vtkvol.engine.illuminator.Illuminator before the technique's own code.
// Tested with VTK 9.7.1 (vtkOpenGLGPUVolumeRayCastMapper, single and independent components).
//
// Spaces: texture = VTK's g_dataPos (0..1 over the data texture, voxel centres at (i+0.5)/N);
// dataset = the image's own µm coordinates (before the vtkVolume's matrix).
// Uniforms (custom, declared by VTK from the host's values):
//   int   vv_numLights            number of enabled lights (0..4)
//   float vv_lights[48]           per light i, floats 12i..12i+11:
//                                 0-2  direction towards the light (directional, unit) or
//                                      position (point), dataset space;
//                                 3    1 for point lights, 0 for directional;
//                                 4-6  colour * intensity (irradiance at the volume's centre);
//                                 7    size: angular radius (rad, directional) or radius (µm,
//                                      point); 0 = ideal light;
//                                 8    inverse-square reference distance d0 (µm); 0 = no fall-off
//                                 9-11 unused

//@inject //VTK::ComputeOpacity::Dec pre before
vec3 vv_texToDataset(vec3 texPos)
{
  return (in_textureDatasetMatrix[0] * vec4(texPos, 1.0)).xyz;
}

vec3 vv_datasetDirToTex(vec3 dirDS)
{
  return (in_inverseTextureDatasetMatrix[0] * vec4(dirDS, 0.0)).xyz;
}

// 0..1 across the volume's point bounds (first to last voxel centre).
vec3 vv_texToUnit(vec3 texPos)
{
  return (texPos - in_texMin[0]) / (in_texMax[0] - in_texMin[0]);
}

// Texture coordinate in an auxiliary grid of `dims` voxels covering the same point bounds.
vec3 vv_unitToGrid(vec3 unitPos, vec3 dims)
{
  return (0.5 + unitPos * (dims - 1.0)) / dims;
}

vec3 vv_lightVector(int i) { return vec3(vv_lights[12*i], vv_lights[12*i+1], vv_lights[12*i+2]); }
bool vv_lightIsPoint(int i) { return vv_lights[12*i+3] > 0.5; }
float vv_lightSize(int i) { return vv_lights[12*i+7]; }

// Colour * intensity of light i arriving at posDS (dataset space): with inverse-square fall-off,
// scaled by (d0 / r)^2 so that the intensity is the irradiance at the volume's centre.
vec3 vv_lightColor(int i, vec3 posDS)
{
  vec3 e = vec3(vv_lights[12*i+4], vv_lights[12*i+5], vv_lights[12*i+6]);
  float d0 = vv_lights[12*i+8];
  if (d0 > 0.0)
  {
    vec3 r = vv_lightVector(i) - posDS;
    e *= (d0 * d0) / max(dot(r, r), 1e-12);
  }
  return e;
}

// Unit direction from a dataset-space position towards light i.
vec3 vv_directionToLight(int i, vec3 posDS)
{
  return vv_lightIsPoint(i) ? normalize(vv_lightVector(i) - posDS) : normalize(vv_lightVector(i));
}
