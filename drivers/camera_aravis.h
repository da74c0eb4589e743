/* camera_aravis.h - private to the "aravis" camera backend
 * (camera_aravis.c: device, camera_aravis_stream.c: acquisition) and the
 * "fake" backend that shares its operations (camera_fake.c). */
#ifndef SL_CAMERA_ARAVIS_H
#define SL_CAMERA_ARAVIS_H

#include <arv.h>

#include "camera.h"

#define POP_SLICE_US 100000       /* lost flag checked this often in pop */
#define PACKET_TIMEOUT_US 20000
#define FRAME_RETENTION_US 100000

typedef struct arvcam {
    char target[CAMERA_STR_MAX];
    ArvCamera *cam;
    ArvDevice *dev;             /* borrowed from cam */
    gulong lost_handler;
    gint lost;                  /* atomic: set from the heartbeat thread */
    ArvStream *stream;          /* NULL unless acquiring */
    size_t payload;             /* bytes per buffer of the stream */
    int acquiring;
    camera_trigger trigger;     /* last set (TriggerMode cannot say which) */
    int trigger_set;
    uint64_t old_missing, old_resent, old_underruns; /* closed streams */
    uint64_t id_gaps, last_id;
    int have_last_id;
    int resuming;               /* reconnected: the next start keeps last_id */
    int fake;                   /* the "fake" backend: Aravis's Fake device only */
    camera_source src;          /* attached to each fake device opened */
} arvcam;

int arvcam_fail(sl_err *err, const arvcam *a, const char *doing, GError *ge);
int arvcam_lost(sl_err *err, const arvcam *a);
camera_pixfmt arvcam_pixfmt(ArvPixelFormat f);

/* Open target (a fake device only when fake); *st on SL_OK. */
int arvcam_open_target(void **st, const char *target, int fake, sl_err *err);
/* After a connect: a fake device gets the source (if any). */
int arvcam_fake_attach(arvcam *a, sl_err *err);

int arvcam_fake_list(camera_info **out, int *n, sl_err *err);
int arvcam_fake_open(void **st, const char *target, sl_err *err);
int arvcam_set_source(void *st, const camera_source *src, sl_err *err);

void arvcam_drop_stream(arvcam *a);
int arvcam_start(void *st, int nbuffers, sl_err *err);
int arvcam_pop(void *st, int timeout_ms, camera_frame *out, sl_err *err);
int arvcam_stop(void *st, sl_err *err);
void arvcam_stats(void *st, camera_stats *out);

#endif
