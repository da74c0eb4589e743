/* soak_load.c - the soak's load phase (soak.h): a run acquired while the
 * machine is busy.  On a bench PC the daemon reconstructs run N while it
 * acquires run N+1, and the operator may be reconstructing or computing
 * beside it, so the load is made of exactly that: the daemon's own
 * reconstruction of the long run (TSM, SOAK_LOAD_PROJECTIONS angles), a
 * separate `specklab recon` of the same cube, and SOAK_LOAD_HOGS
 * processes that only spin.  The run (no reconstruction of its own) must
 * end done with every frame, which soak_check_files checks with the
 * others; the 1-minute load average is sampled while it acquires.
 */
#include "daemon_fx.h"

#include "soak.h"

#define MAX_HOGS 64

/* A process that only spins (dies with the soak). */
static pid_t hog_start(void)
{
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        for (volatile unsigned long n = 0;; n++)
            ;
    }
    return pid;
}

static double loadavg_1min(void)
{
    double la = NAN;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f && fscanf(f, "%lf", &la) != 1)
        la = NAN;
    if (f)
        fclose(f);
    return la;
}

/* `status` says the daemon reconstructs run uuid (its reconstruction has
 * started); 0, or -1 after timeout_s. */
static int reconstructing(soak *s, const char *uuid, double timeout_s)
{
    double end = fx_now() + timeout_s;
    while (fx_now() < end) {
        JsonNode *r = dc_call(s->c, "status", NULL, 5);
        int yes = r && !g_strcmp0(js(r, "result.reconstructing"), uuid);
        if (r)
            json_node_unref(r);
        if (yes)
            return 0;
        fx_nap_ms(50);
    }
    return -1;
}

/* Acquire the load run; the run's index, or -1. */
static int load_run(soak *s)
{
    const soak_opts *o = &s->o;
    int i = soak_submit(s, 2, 0, o->load_frames, "none");
    double until = fx_now() + 60 + 4.0 * o->load_frames / o->rate_hz;
    s->load.loadavg_max = loadavg_1min();
    while (i >= 0 && !(s->runs[i].t_stored > 0)) {
        double la = loadavg_1min();
        if (la > s->load.loadavg_max)
            s->load.loadavg_max = la;
        if (soak_pump(s, until) != 0) {
            soak_problem(s, "the load run did not leave acquisition within its bound "
                         "(state %s)", s->runs[i].state);
            break;
        }
    }
    if (i >= 0 && s->runs[i].t_full > s->runs[i].t_acq)
        s->load.acq_s = s->runs[i].t_full - s->runs[i].t_acq;
    return i;
}

void soak_load(soak *s)
{
    const soak_opts *o = &s->o;
    char args[200], cube[400], out[300], errlog[300], bin[PATH_MAX], proj[16];
    pid_t hogs[MAX_HOGS];
    if (o->load_frames == 0 || s->nruns == 0)
        return;
    soak_run *lr = &s->runs[0];
    int nhogs = MIN(o->load_hogs, MAX_HOGS);
    printf("soak: load phase: %d frames while the daemon and `specklab recon` reconstruct "
           "the long run (tsm, %d angles) and %d hog%s spin\n", o->load_frames,
           o->load_projections, nhogs, nhogs == 1 ? "" : "s");
    fflush(stdout);
    /* On a connection of its own: its reply comes when it is done, and a
     * connection's replies keep request order. */
    dc *rc = bench_client(&s->b);
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"method\": \"tsm\", \"projections\": %d}",
             lr->uuid, o->load_projections);
    gint64 id = rc ? dc_send(rc, "reconstruct", args) : -1;
    lr->reconstructs++;   /* the row it adds */
    if (id < 0 || reconstructing(s, lr->uuid, 60) != 0) {
        soak_problem(s, "the daemon's reconstruction of the long run did not start");
        return;
    }
    snprintf(cube, sizeof cube, "%s/runs/%s.fits", s->b.data, lr->uuid);
    snprintf(out, sizeof out, "%s/load-recon.fits", s->b.dir);
    snprintf(errlog, sizeof errlog, "%s/load-recon.log", s->b.dir);
    snprintf(proj, sizeof proj, "%d", o->load_projections);
    fx_bin(bin, sizeof bin, "specklab");
    char *argv[] = {bin, "recon", cube, "-m", "tsm", "-p", proj, "-o", out, "-q", NULL};
    fx_proc ext;
    int ext_up = fx_spawn(&ext, argv, errlog, NULL, NULL) == 0;
    for (int h = 0; h < nhogs; h++)
        hogs[h] = hog_start();
    s->load.hogs = nhogs;
    s->load.run = load_run(s);
    JsonNode *st = dc_call(s->c, "status", NULL, 5);
    s->load.recon_spanned = st && !g_strcmp0(js(st, "result.reconstructing"), lr->uuid);
    if (st)
        json_node_unref(st);
    for (int h = 0; h < nhogs; h++)
        if (hogs[h] > 0)
            kill(hogs[h], SIGKILL), waitpid(hogs[h], NULL, 0);
    /* Still reconstructing when the frames were in: it was load all along. */
    int ws = 0;
    pid_t w = ext_up ? waitpid(ext.pid, &ws, WNOHANG) : -1;
    s->load.external_spanned = w == 0;
    s->load.external_ok = w == 0 || (w > 0 && WIFEXITED(ws) && WEXITSTATUS(ws) == 0);
    if (w == 0)
        fx_stop(&ext, SIGTERM, 10);
    else if (ext_up)
        close(ext.out);
    if (!s->load.external_ok)
        soak_problem(s, "`specklab recon` of the long run failed (see %s)", errlog);
    JsonNode *r = dc_wait_reply(rc, id, 900);
    s->load.recon_ok = jok(r);
    if (!s->load.recon_ok)
        soak_problem(s, "the daemon's reconstruction under load: %s", jtext(r));
    if (r)
        json_node_unref(r);
}
