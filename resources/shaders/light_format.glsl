// Image format of a texture holding one light per channel: VV_CHANNELS 1, 2 or 4 lights.
#if VV_CHANNELS == 1
#define VV_FORMAT r32f
#elif VV_CHANNELS == 2
#define VV_FORMAT rg32f
#else
#define VV_FORMAT rgba32f
#endif
