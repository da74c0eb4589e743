/* fakecam_app.h - the parts of bin/specklab-fake-camera (not a library:
 * nothing outside mocks/fake-camera includes this). */
#ifndef SL_FAKECAM_APP_H
#define SL_FAKECAM_APP_H

#include <arv.h>

#include "fakecam.h"

/* What the stage has in the beam.  known = 0 until the stage answered
 * (or, without --stage, never 0); moving = a wheel is between slots,
 * unhomed, busy or faulted: the beam is blocked and frames are dark. */
typedef struct beam {
    int known, moving;
    int screen, mask;   /* slots, valid when known && !moving */
} beam;

/* ---- render.c: the fill-pattern callback and its simulator cache ---- */

typedef struct renderer renderer;

/* masks[0..nmasks) become the renderer's (freed by renderer_free, also
 * on failure). */
int renderer_new(renderer **out, const fakecam_model *m, mask **masks,
                 int nmasks, sl_err *err);
void renderer_free(renderer *r);
/* The fake camera whose registers (ROI, binning) the callback reads. */
void renderer_attach(renderer *r, ArvFakeCamera *fake);
/* A fresh fake camera as the mocks start it: the model's sensor size, the
 * whole sensor as ROI, Mono16.  The ExposureTime register is returned. */
guint32 renderer_init_camera(const renderer *r, ArvFakeCamera *fake);
/* Set the beam (main thread); the next frame uses it. */
void renderer_set_beam(renderer *r, const beam *b);
/* Make the simulator of the current beam now rather than on the first
 * frame (sim_new plans FFTs: tens of ms). */
int renderer_prepare(renderer *r, uint32_t exposure_us, uint32_t gain, sl_err *err);
/* ArvFakeCameraFillPattern: data is the renderer. */
void renderer_fill(ArvBuffer *buffer, void *data, guint32 exposure_us,
                   guint32 gain, ArvPixelFormat pixel_format);
/* The same for a camera that frames its own stream (the U3V mock): frame
 * frame_id at w x h in that format into dst (payload bytes), the ROI
 * offsets and binning read from the attached fake camera. */
void renderer_render(renderer *r, uint64_t frame_id, int w, int h, ArvPixelFormat pixel_format,
                     uint32_t exposure_us, uint32_t gain, unsigned char *dst, size_t payload);
void renderer_counts(renderer *r, uint64_t *rendered, uint64_t *dark);

/* ---- stage_poll.c: the fake stage, read over Modbus/TCP ---- */

typedef struct stage_poll stage_poll;

/* host_port is "HOST:PORT"; nothing is contacted yet. */
int stage_poll_new(stage_poll **out, const char *host_port, int unit, sl_err *err);
void stage_poll_free(stage_poll *p);
/* One bounded poll (<= ~0.3 s): both wheels' POSITION and STATUS.
 * SL_OK with *out set, or SL_EIO (out untouched) when the stage did not
 * answer; the connection is then dropped and re-made on a later call
 * with a backoff of 100 ms doubling to 2 s. */
int stage_poll_read(stage_poll *p, beam *out, sl_err *err);

/* ---- model_args.c: option values shared by the camera mocks ---- */

/* --size: "N" or "WxH", 8..4096. */
int fakecam_parse_size(const char *text, int *w, int *h, sl_err *e);
/* --screen-r0: "inf,0.25,0.15": r0 [m] per screen slot, inf = open. */
int fakecam_parse_r0(const char *text, fakecam_model *m, sl_err *e);
/* --mask-slots: "full,nrm17,closed,FILE"; masks[0..*n) are the caller's. */
int fakecam_load_masks(const char *text, mask **masks, int *n, sl_err *e);
/* The model from defaults and the three options above; the masks are the
 * caller's on success, none is left on failure. */
int fakecam_model_from_args(const char *size, const char *screen_r0, const char *mask_slots,
                            fakecam_model *m, mask **masks, int *nmasks, sl_err *e);

#endif
