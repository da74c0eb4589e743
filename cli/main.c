/* main.c - `specklab COMMAND [OPTIONS]`: dispatch to the subcommands. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cmd_daemon.h"
#include "jsonmode.h"
#include "base/version.h"
#include "base/wisdom.h"

typedef struct command {
    const char *name;
    int (*run)(int argc, char **argv);
    const char *summary;
} command;

static const command commands[] = {
    {"sim", cmd_sim, "simulate a speckle cube (scene, mask, turbulence, detector)"},
    {"experiment", cmd_experiment, "run an experiment on the bench (binary-bench) through specklabd"},
    {"runs", cmd_runs, "catalogued runs: list, show"},
    {"screens", cmd_screens, "phase screens with their measured seeing: list, show"},
    {"masks", cmd_masks, "aperture masks on the bench: list"},
    {"export", cmd_export, "export a run: FITS, reconstructions and a JSON sidecar"},
    {"daemon", cmd_daemon, "specklabd status and devices"},
    {"recon", cmd_recon, "reconstruct a FITS sequence (direct bispectrum or TSM)"},
    {"compare", cmd_compare, "correlation coefficient c of two images"},
    {"binary", cmd_binary, "separation, position angle and dm of a binary image"},
    {"oifits", cmd_oifits, "an aperture-mask cube's V2 and closure phases as OIFITS 2"},
    {"bench", cmd_bench, "run time against error of every method on simulated cubes (table, CSV, PNG, catalogue)"},
    {"mask", cmd_mask, "generate or show an aperture mask"},
    {"devices", cmd_devices, "cameras and stages found, with diagnosis (USB speed, permissions)"},
    {"camera", cmd_camera, "machine-vision cameras: list, info, grab frames to a FITS cube"},
    {"stage", cmd_stage, "home, move, stop or reset the stage wheels, or show their status"},
};

/* Commands that plan FFTs start from the saved FFTW wisdom and save what
 * they measured, and measure within a bounded time per plan, so a size
 * never seen costs ~0.1 s of planning, not ~1 s.  Wisdom problems only
 * warn: they cost speed, never results. */
static int run_with_wisdom(const command *c, int argc, char **argv)
{
    int plans = !strcmp(c->name, "sim") || !strcmp(c->name, "recon") ||
                !strcmp(c->name, "bench") || !strcmp(c->name, "oifits");
    const char *path = plans ? wisdom_default_path() : NULL;
    sl_err e = {0};
    if (path && wisdom_load(path, NULL, &e) != SL_OK)
        fprintf(stderr, "specklab: warning: %s\n", e.msg);
    if (plans)
        wisdom_plan_limit(WISDOM_PLAN_LIMIT_S);
    int status = c->run(argc, argv);
    if (path && status == 0 && wisdom_save(path, &e) != SL_OK)
        fprintf(stderr, "specklab: warning: %s\n", e.msg);
    return status;
}

static void usage(FILE *f)
{
    fprintf(f, "Usage: specklab COMMAND [OPTION]...\n"
               "  or:  specklab --version\n"
               "Each command's options: specklab COMMAND --help\n\n"
               "Commands:\n");
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(f, "  %-12s %s\n", commands[i].name, commands[i].summary);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "help") || !strcmp(argv[1], "--help") ||
        !strcmp(argv[1], "-h")) {
        usage(stdout);
        return 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("specklab %s\n", SPECKLAB_VERSION);
        return 0;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        if (strcmp(argv[1], commands[i].name) == 0) {
            char name[64];
            snprintf(name, sizeof name, "specklab %s", commands[i].name);
            argv[1] = name;
            jsonmode jm = {0};
            if (jsonmode_wanted(argc - 1, argv + 1))
                jsonmode_begin(&jm);
            int status = run_with_wisdom(&commands[i], argc - 1, argv + 1);
            return jsonmode_end(&jm, commands[i].name, status);
        }
    }
    fprintf(stderr, "specklab: unknown command '%s'\n\n", argv[1]);
    usage(stderr);
    return 2;
}
