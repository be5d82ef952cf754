/* smplpix: the SMPLpix neural avatar renderer on OpenCL. Umbrella header. */
#ifndef SMPLPIX_H
#define SMPLPIX_H

#include "smplpix/core.h"
#include "smplpix/device.h"
#include "smplpix/render.h"

#endif
