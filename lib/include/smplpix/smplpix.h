/* smplpix: the SMPLpix neural avatar renderer on OpenCL. Umbrella header. */
#ifndef SMPLPIX_H
#define SMPLPIX_H

#include "smplpix/core.h"
#include "smplpix/device.h"
#include "smplpix/image.h"
#include "smplpix/safetensors.h"
#include "smplpix/unet.h"

#endif
