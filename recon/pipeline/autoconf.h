/* autoconf.h - choose a reconstruction configuration from the scene probe
 * (probe.h): the cheapest one a calibrated model expects to meet a target
 * error.  Model and calibration: autoconf.c. */
#ifndef SL_AUTOCONF_H
#define SL_AUTOCONF_H

#include "probe.h"

typedef struct autoconf_choice {
    int chosen;             /* 0: nothing chosen (fields below unset) */
    int method;             /* PIPE_DIRECT, PIPE_TSM or PIPE_TSM_FOURIER */
    int nangles;            /* TSM projections */
    int inverse;            /* TSM_INV_* */
    int crop_level;         /* probe crop level (probe_set_crop) */
    double cutoff_cyc_px;   /* TSM cut-off; 0: Nyquist */
    double pred_error;      /* the model's 1 - c */
    double pred_cost;       /* the model's cost, CPU seconds (bench machine) */
    int meets;              /* pred_error <= target */
} autoconf_choice;

/* The TSM cut-off following the measured support: 0 (Nyquist) unless the
 * support ends inside 0.9 Nyquist. */
double autoconf_cutoff(const probe_scene *sc);
/* The model's 1 - c and cost for one configuration on the probed scene,
 * nframes frames kept. */
double autoconf_error(const probe_scene *sc, int nframes, int method,
                      int nangles, double cutoff_cyc_px);
double autoconf_cost(const probe_scene *sc, int nframes, int method,
                     int nangles, double cutoff_cyc_px);
/* Choose.  method: PIPE_AUTO (any) or a fixed method; angles: 1 to pick
 * the projections, else nangles_fixed (0: 180) is used; support: 1 to cut
 * TSM at the measured support.  target: the 1 - c wanted (0: 0.1).  When
 * nothing meets the target, the configuration with the smallest predicted
 * error (meets = 0). */
void autoconf_choose(const probe_scene *sc, int nframes, int method,
                     int angles, int nangles_fixed, int support, int crop,
                     double target, autoconf_choice *c);
/* "tsm-fourier 48 angles, cut-off 0.31" into buf. */
void autoconf_label(const autoconf_choice *c, char *buf, int n);

#endif
