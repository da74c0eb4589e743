/* fakesrc.h - the speckle simulator as the pixel source of the "fake"
 * camera backend (drivers/camera.h, camera_source): the frames of
 * bin/specklab-fake-camera (fakecam.h defines them), rendered inside the
 * process that drives Aravis's in-process fake camera.
 *
 * args are bin/specklab-fake-camera's flags that choose the frames, in
 * shell syntax: --serial --size --seed --screen-r0 --mask-slots --screen-slot
 * --mask-slot --dm-mag --sep-arcsec --pa-deg and the stage ones, --stage
 * HOST:PORT --stage-unit --stage-poll-ms, with the same defaults.  With
 * --stage a thread polls the fake stage (the first answer, bounded, is
 * waited for by fakesrc_new) and the beam follows its wheels as in the
 * GigE mock; without, --screen-slot and --mask-slot fix it.
 *
 * Users: tests that link mocks/camsrc attach it with camera_set_source;
 * bin/specklab-fake-source.so (mocks/fake-source) exports it as
 * CAMERA_SOURCE_ENTRY for specklabd, which must not link a mock.
 */
#ifndef SL_FAKESRC_H
#define SL_FAKESRC_H

#include "camera.h"

/* out->release frees what out->data holds (call it if the source is never
 * given to a camera). */
int fakesrc_new(camera_source *out, const char *args, sl_err *err);

#endif
