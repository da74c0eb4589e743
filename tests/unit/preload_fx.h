/* preload_fx.h - running a test binary under umockdev's preload library
 * (what umockdev-wrapper does): with it, /sys and /dev paths and usbfs
 * ioctls go to the testbed named by $UMOCKDEV_DIR.  Used by the USB
 * driver tests and the integration tests that start a U3V mock camera.
 */
#ifndef SL_TEST_PRELOAD_FX_H
#define SL_TEST_PRELOAD_FX_H

#include <errno.h>
#include <glib.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PRELOAD_LIB "libumockdev-preload.so.0"

/* Is the preload library mapped in this process (not merely named in
 * $LD_PRELOAD: ld.so skips a library it cannot load)? */
static inline int fx_preloaded(void)
{
    char line[1024];
    int found = 0;
    FILE *maps = fopen("/proc/self/maps", "r");
    while (maps && !found && fgets(line, sizeof line, maps))
        found = strstr(line, "/libumockdev-preload.so") != NULL;
    if (maps)
        fclose(maps);
    return found;
}

/* $LD_PRELOAD with the umockdev library in it (newly allocated).  A
 * sanitized build must keep libasan first in the library list, so it is
 * put in front when this process has it. */
static inline char *fx_preload_value(void)
{
    char line[1024], asan[1024] = "";
    FILE *maps = fopen("/proc/self/maps", "r");
    while (maps && !asan[0] && fgets(line, sizeof line, maps)) {
        char *p = strchr(line, '/');
        if (p && strstr(p, "/libasan.so")) {
            p[strcspn(p, "\n")] = '\0';
            g_strlcpy(asan, p, sizeof asan);
        }
    }
    if (maps)
        fclose(maps);
    const char *old = getenv("LD_PRELOAD");
    return g_strdup_printf("%s%s%s%s%s", asan, asan[0] ? ":" : "", PRELOAD_LIB,
                           old && *old ? ":" : "", old ? old : "");
}

/* Re-run this binary under the preload, once (guard names an environment
 * variable set for the second run).  Returns only when it did not. */
static inline void fx_reexec_preloaded(char **argv, const char *guard)
{
    if (fx_preloaded() || getenv(guard))
        return;
    setenv(guard, "1", 1);
    char *pre = fx_preload_value();
    setenv("LD_PRELOAD", pre, 1);
    g_free(pre);
    execv("/proc/self/exe", argv);
    fprintf(stderr, "%s: cannot re-exec under %s: %s\n", argv[0], PRELOAD_LIB,
            strerror(errno));
}

#endif
