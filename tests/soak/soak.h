/* soak.h - the state shared by the soak's sequence (soak.c) and its
 * after-the-fact checks of files and catalogue (soak_check.c).  Include
 * after daemon_fx.h (the bench and the protocol client). */
#ifndef SL_SOAK_H
#define SL_SOAK_H

#define SOAK_MAX_RUNS 1001

typedef struct soak_opts {
    int long_frames, runs, short_frames, warm_runs, buffers;
    int load_frames, load_hogs, load_projections;   /* the load phase (soak_load.c) */
    double rate_hz, exposure_us, rss_bound_mb;
    char size[16];
    char long_method[16];
} soak_opts;

typedef struct proc_sample {
    long rss_kb, hwm_kb;   /* VmRSS, VmHWM */
    int fds;               /* entries of /proc/PID/fd */
    double cpu_s;          /* utime + stime */
} proc_sample;

typedef struct soak_run {
    char uuid[40];
    char state[16];        /* the last state event */
    int frames, screen, mask;
    int reconstructs;      /* reconstruction rows it must end with */
    gint64 progress;       /* the last progress event's frames_acquired */
    double t_acq, t_full, t_stored;  /* fx_now() at acquiring, at the progress
                                      * event of the last frame, at stored (or
                                      * an end) */
    double cpu_acq, cpu_full;  /* the daemon's CPU seconds then */
} soak_run;

/* Frame accounting over every run, from the files and the catalogue. */
typedef struct soak_frames {
    long requested, naxis3, catalogued;
    long lost;             /* SUCCESS rows of FRAMES not in the cube */
    long damaged;          /* rows of another status (never stored) */
    long gaps;             /* frame ids never delivered, from the table */
    long gaps_unaccounted; /* runs whose gaps differ from NIDGAPS */
} soak_frames;

typedef struct soak_disk {
    int run_rows, recon_rows, files, mismatches;
} soak_disk;

/* What the load phase saw (soak_load.c). */
typedef struct soak_load_facts {
    int run;               /* its run's index, -1: none */
    double loadavg_max;    /* 1-minute load average while it acquired */
    double acq_s;          /* acquiring to its last frame */
    int hogs, recon_ok, external_ok;
    int recon_spanned, external_spanned;   /* still running at its last frame */
} soak_load_facts;

typedef struct soak {
    soak_opts o;
    soak_load_facts load;
    bench b;
    dc *c;
    soak_run runs[SOAK_MAX_RUNS];
    int nruns, ndone;
    long frames_seen;
    proc_sample start, base, end, peak;
    long peak_after_warm_kb, last_rss_kb;
    int last_fds, warm_done, log_warnings;
    double t0, t_sample, t_report;
    soak_frames f;
    soak_disk disk;
    GString *problems;
    int nproblems;
} soak;

/* soak.c's steps, shared with soak_load.c: take one event (0; -1 when
 * until passed), start a run (its index, or -1), wait until run i has
 * left acquisition. */
int soak_pump(soak *s, double until);
int soak_submit(soak *s, int screen, int mask, int frames, const char *method);
int soak_wait_stored(soak *s, int i, double timeout_s);

/* The load phase: a run of o.load_frames acquired while the daemon
 * reconstructs the long run with TSM, a separate `specklab recon` does
 * the same and o.load_hogs processes spin; fills s->load.  The run is
 * checked with the others by soak_check_files. */
void soak_load(soak *s);

/* Record (and print at once) a reason the soak fails. */
void soak_problem(soak *s, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Every run's cube against the catalogue and its FRAMES table, then the
 * files under runs/ and recon/ against the catalogue's rows; fills s->f
 * and s->disk.  Call with the daemon stopped. */
void soak_check_files(soak *s);

#endif
