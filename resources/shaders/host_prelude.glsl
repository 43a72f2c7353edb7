// vtkvol host prelude: coordinate helpers and light uniforms shared by every technique.
// Injected by vtkvol.engine.illuminator.Illuminator before the technique's own code.
// Tested with VTK 9.7.1 (vtkOpenGLGPUVolumeRayCastMapper, single and independent components).
//
// Spaces: texture = VTK's g_dataPos (0..1 over the data texture, voxel centres at (i+0.5)/N);
// dataset = the image's own µm coordinates (before the vtkVolume's matrix).
// Uniforms (custom, declared by VTK from the host's values):
//   int   vv_numLights            number of enabled lights (0..4)
//   float vv_lights[32]           per light i, floats 8i..8i+7:
//                                 xyz = direction towards the light (directional, unit) or
//                                       position (point), dataset space; w = 1 for point lights;
//                                 rgb = colour * intensity; last float unused

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

vec3 vv_lightVector(int i) { return vec3(vv_lights[8*i], vv_lights[8*i+1], vv_lights[8*i+2]); }
bool vv_lightIsPoint(int i) { return vv_lights[8*i+3] > 0.5; }
vec3 vv_lightColor(int i) { return vec3(vv_lights[8*i+4], vv_lights[8*i+5], vv_lights[8*i+6]); }

// Unit direction from a dataset-space position towards light i.
vec3 vv_directionToLight(int i, vec3 posDS)
{
  return vv_lightIsPoint(i) ? normalize(vv_lightVector(i) - posDS) : normalize(vv_lightVector(i));
}
