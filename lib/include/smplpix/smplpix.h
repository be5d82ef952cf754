/* smplpix: the SMPLpix neural avatar renderer on OpenCL. Umbrella header. */
#ifndef SMPLPIX_H
#define SMPLPIX_H

#include "smplpix/core.h"
#include "smplpix/files.h"
#include "smplpix/comm.h"
#include "smplpix/device.h"
#include "smplpix/raster.h"

#include "smplpix/camera.h"
#include "smplpix/depth.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/npy.h"
#include "smplpix/npz.h"
#include "smplpix/safetensors.h"
#include "smplpix/bvh.h"
#include "smplpix/amass.h"

#include "smplpix/render.h"

#include "smplpix/body.h"
#include "smplpix/synth.h"
#include "smplpix/unet.h"
#include "smplpix/vgg.h"
#include "smplpix/patchgan.h"
#include "smplpix/fit.h"
#include "smplpix/bake.h"
#include "smplpix/metrics.h"
#include "smplpix/avatar.h"

#endif
