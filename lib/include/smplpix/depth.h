/* Depth images as depth cameras write them (lib/io/depth.c).
 *
 * Formats, by extension:
 *   .png  one-channel 16-bit PNG in millimetres (Kinect, RealSense, Azure Kinect, OpenNI);
 *         0 is no data
 *   .exr  the Z channel in metres; 0, NaN and +inf are no data, and so is Z = 1 exactly: the
 *         background of smplpix's own RGB-D images (`smplpix project`)
 *   .npy  an HxW (or HxWx1) float16/32/64 array in metres; 0, NaN and +inf are no data
 * Every image is checked before any use: a negative depth, no pixel with depth, every pixel at one
 * depth, depth in the wrong unit (a PNG whose median depth is under 100 mm looks like metres or
 * decimetres; an EXR or NPY whose median depth is over 30 looks like millimetres; an 8-bit PNG
 * cannot hold millimetres) are SPX_E_FORMAT, each message one line that names the file.
 *
 * With the image's camera (its intrinsics K, e.g. a real 640x480 or 1280x720 sensor's, in a camera
 * JSON), the image must be the camera's size, and K must be an image of this size's: principal
 * point within the middle half of the image, focal lengths 0.25-8 times the width, fx/fy within
 * 0.8-1.25 (otherwise SPX_E_CAMERA naming both files): K of a 1280x720 sensor given with its
 * 640x480 image is refused instead of back-projecting every pixel in the wrong direction. */
#ifndef SMPLPIX_DEPTH_H
#define SMPLPIX_DEPTH_H

#include "smplpix/camera.h"
#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_depth {
  int32_t width, height;
  float *z;       /* height*width, row-major: depth along the optical axis in metres, 0 = no data */
  int64_t nvalid; /* pixels with depth */
} spx_depth;

/* Read the depth image at path. cam (NULL: not checked) is its camera, cam_name the camera's file
 * for the messages (NULL: "its camera"). out: free with spx_depth_free. */
spx_status spx_depth_read(spx_ctx *ctx, const char *path, const spx_camera *cam, const char *cam_name,
                          spx_depth *out);
/* The checks of spx_depth_read on depth already in memory (metres, 0 / NaN / +inf = no data; no
 * data is set to 0 in place). name labels the messages; unit_png: the values came from a 16-bit
 * PNG in millimetres (the unit check then says so). */
spx_status spx_depth_check(spx_ctx *ctx, const char *name, float *z, int32_t width, int32_t height, int unit_png,
                           int64_t *nvalid);
/* The camera check of spx_depth_read: cam's size is width x height and its K fits such an image. */
spx_status spx_depth_check_camera(spx_ctx *ctx, const char *name, int32_t width, int32_t height,
                                  const spx_camera *cam, const char *cam_name);
void spx_depth_free(spx_depth *d);

#ifdef __cplusplus
}
#endif
#endif
