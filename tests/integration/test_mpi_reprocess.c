/* test_mpi_reprocess.c - `mpirun -n 2 specklab-mpi reprocess`: 20
 * catalogued runs (tiny cubes) get 20 new reconstruction rows, each with
 * its image, and the catalogue passes its integrity check; rank 1 killed
 * mid-job (SIGKILL, once rank 0 has recorded two runs) ends the job
 * non-zero with the rank named, and leaves a consistent catalogue whose
 * rows are exactly runs done, each with its image.  Skipped, with the
 * reason, when the build has no MPI (Makefile, MPI). */
#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "catalog.h"
#include "tcheck.h"
#include "tmpdir_fx.h"

#ifndef SL_HAVE_MPI
#define SL_HAVE_MPI 0
#endif

#define NRUNS 20

/* One integer from sql on its own connection; -1 on error. */
static long long raw_int(const char *db_path, const char *sql)
{
    sqlite3 *db = NULL;
    sqlite3_stmt *st = NULL;
    long long v = -1;
    if (sqlite3_open_v2(db_path, &db, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK &&
        sqlite3_busy_timeout(db, 5000) == SQLITE_OK &&
        sqlite3_prepare_v2(db, sql, -1, &st, NULL) == SQLITE_OK && sqlite3_step(st) == SQLITE_ROW)
        v = sqlite3_column_int64(st, 0);
    sqlite3_finalize(st);
    sqlite3_close(db);
    return v;
}

/* A catalogue of NRUNS done runs, each with the same small cube. */
static int make_catalogue(tmpdir *d, char *db, size_t n, char *msg, size_t nmsg)
{
    char cube[300], cmd[800];
    snprintf(cube, sizeof cube, "%s/cube.fits", d->dir);
    snprintf(db, n, "%s/specklab.db", d->dir);
    snprintf(cmd, sizeof cmd, "bin/specklab sim --scene binary --size 64 --frames 16 "
             "--photons 1e4 -o %s >/dev/null 2>&1", cube);
    if (system(cmd) != 0)
        return snprintf(msg, nmsg, "specklab sim failed"), -1;
    catalog *c = NULL;
    sl_err e = {0};
    if (catalog_open(&c, db, &e) != SL_OK)
        return snprintf(msg, nmsg, "catalog_open: %s", e.msg), -1;
    static const catalog_state path[] = {CATALOG_MOVING, CATALOG_ACQUIRING,
                                         CATALOG_STORED, CATALOG_DONE};
    int rc = SL_OK;
    for (int i = 0; i < NRUNS && rc == SL_OK; i++) {
        catalog_run_spec s = {.frames_requested = 16, .object = "HD 1"};
        char uuid[CATALOG_UUID_LEN + 1];
        rc = catalog_run_insert(c, &s, uuid);
        for (size_t k = 0; k < 4 && rc == SL_OK; k++)
            rc = catalog_run_set_state(c, uuid, path[k], NULL);
        if (rc == SL_OK)
            rc = catalog_run_set_file(c, uuid, cube, NULL);
    }
    if (rc != SL_OK)
        snprintf(msg, nmsg, "catalogue: %s", catalog_errmsg(c));
    catalog_close(c);
    return rc == SL_OK ? 0 : -1;
}

/* mpirun ... reprocess, started (not waited for): its pid; output to log. */
static pid_t start_job(const tmpdir *d, const char *db, const char *log)
{
    pid_t pid = fork();
    if (pid != 0)
        return pid;
    int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    char out[300];
    snprintf(out, sizeof out, "%s/images", d->dir);
    execlp("mpirun", "mpirun", "--oversubscribe", "-n", "2", "bin/specklab-mpi", "reprocess",
           "--catalog", db, "--method", "tsm", "--out-dir", out, (char *)NULL);
    _exit(127);
}

static int wait_exit(pid_t pid)
{
    int st = 0;
    while (waitpid(pid, &st, 0) < 0)
        ;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/* The child of mpirun that is rank 1, from its environment. */
static pid_t rank1_of(pid_t mpirun)
{
    DIR *dp = opendir("/proc");
    struct dirent *e;
    pid_t found = 0;
    while (!found && dp && (e = readdir(dp))) {
        char p[300], buf[16384];
        long ppid = 0;
        snprintf(p, sizeof p, "/proc/%s/stat", e->d_name);
        FILE *f = fopen(p, "r");
        if (!f)
            continue;
        int ok = fscanf(f, "%*d %*s %*c %ld", &ppid) == 1;
        fclose(f);
        if (!ok || ppid != mpirun)
            continue;
        snprintf(p, sizeof p, "/proc/%s/environ", e->d_name);
        int fd = open(p, O_RDONLY);
        ssize_t n = fd >= 0 ? read(fd, buf, sizeof buf - 1) : 0;
        if (fd >= 0)
            close(fd);
        for (ssize_t i = 0; i < n; i += (ssize_t)strlen(buf + i) + 1)
            if (!strcmp(buf + i, "OMPI_COMM_WORLD_RANK=1"))
                found = (pid_t)atol(e->d_name);
    }
    if (dp)
        closedir(dp);
    return found;
}

/* Every row's run exists and is done, every row's image exists. */
static int rows_consistent(const char *db)
{
    return raw_int(db, "SELECT count(*) FROM reconstructions r LEFT JOIN runs u "
                       "ON u.uuid = r.run_uuid WHERE u.state IS NOT 'done'") == 0;
}

static int images_exist(const tmpdir *d, long long rows)
{
    char p[300];
    snprintf(p, sizeof p, "%s/images", d->dir);
    DIR *dp = opendir(p);
    long long n = 0;
    for (struct dirent *e; dp && (e = readdir(dp));)
        n += strstr(e->d_name, ".fits") != NULL;
    if (dp)
        closedir(dp);
    return n >= rows;
}

/* After the job: its output, the rows, the catalogue's checks; the
 * directory removed. */
typedef struct outcome {
    char text[8192];
    long long rows;
    int integrity, consistent, images;
} outcome;

static void job_outcome(tmpdir *d, const char *db, const char *log, outcome *o)
{
    memset(o, 0, sizeof *o);
    FILE *f = fopen(log, "r");
    if (f)
        o->text[fread(o->text, 1, sizeof o->text - 1, f)] = 0, fclose(f);
    o->rows = raw_int(db, "SELECT count(*) FROM reconstructions");
    catalog *c = NULL;
    sl_err e = {0};
    o->integrity = catalog_open(&c, db, &e) == SL_OK ? catalog_integrity_check(c) : -1;
    catalog_close(c);
    o->consistent = rows_consistent(db);
    o->images = images_exist(d, o->rows);
    tmp_remove(d);
}

/* mpirun as root (CI) and the catalogue in d; db and log: 300 chars. */
static int prepare(tmpdir *d, char *db, char *log, char *msg, size_t nmsg)
{
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    snprintf(log, 300, "%s/log", d->dir);
    return make_catalogue(d, db, 300, msg, nmsg);
}

TEST(two_ranks_record_every_run)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0) "
             "(apt-get install libopenmpi-dev openmpi-bin)");
    tmpdir d;
    char db[300], log[300], msg[600] = "";
    CHECK(tmp_make(&d), "mkdtemp");
    int made = prepare(&d, db, log, msg, sizeof msg);
    int rc = made == 0 ? wait_exit(start_job(&d, db, log)) : -1;
    outcome o;
    job_outcome(&d, db, log, &o);
    CHECK(made == 0, "%s", msg);
    CHECK(rc == 0, "exit %d: %s", rc, o.text);
    CHECK(o.rows == NRUNS, "%lld reconstruction rows for %d runs: %s", o.rows, NRUNS, o.text);
    CHECK(o.integrity == SL_OK, "integrity check: %d", o.integrity);
    CHECK(o.consistent && o.images, "rows without their run or image");
    CHECK(strstr(o.text, "reprocessed 20 of 20 runs on 2 ranks"), "summary: %s", o.text);
}

TEST(killed_rank_ends_the_job_named_catalogue_consistent)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0)");
    tmpdir d;
    char db[300], log[300], msg[600] = "";
    CHECK(tmp_make(&d), "mkdtemp");
    int made = prepare(&d, db, log, msg, sizeof msg);
    pid_t job = made == 0 ? start_job(&d, db, log) : -1, victim = 0;
    long long seen = 0;
    /* readiness: two rows recorded (rank 0 writes one per run done) */
    for (int i = 0; made == 0 && i < 200000 && seen < 2; i++) {
        seen = raw_int(db, "SELECT count(*) FROM reconstructions");
        if (seen < 2 && waitpid(job, NULL, WNOHANG) == job) {
            job = -1;
            break;
        }
        usleep(1000);
    }
    if (job > 0 && (victim = rank1_of(job)) > 0)
        kill(victim, SIGKILL);
    int rc = job > 0 ? wait_exit(job) : -1;
    outcome o;
    job_outcome(&d, db, log, &o);
    CHECK(made == 0, "%s", msg);
    CHECK(victim > 0, "no rank 1 found to kill (job ended early? %lld rows): %s", seen, o.text);
    CHECK(rc != 0, "exit 0 after rank 1 was killed: %s", o.text);
    const char *named = strstr(o.text, "process rank 1");
    CHECK(named, "the dead rank is not named: %s", o.text);
    const char *bol = named;
    while (bol > o.text && bol[-1] != '\n')
        bol--;
    printf("  after %lld rows, exit %d: %.*s\n", seen, rc, (int)strcspn(bol, "\n"), bol);
    CHECK(o.rows >= 2 && o.rows < NRUNS, "%lld rows after the kill", o.rows);
    CHECK(o.integrity == SL_OK, "integrity check: %d", o.integrity);
    CHECK(o.consistent && o.images, "rows without their run or image");
}

TC_MAIN(TC_CASE(two_ranks_record_every_run),
        TC_CASE(killed_rank_ends_the_job_named_catalogue_consistent))
