/*
 * tsio_stage.c - a job's outputs, all or nothing, and what a signal leaves.
 *
 * Every output is written to a temporary name beside its final one
 * (".<stem>.tmp<pid>.<ext>", tsio_common.c).  Outside a stage it is moved
 * into place as soon as it is written; inside one (tsio_stage_begin) it
 * waits there until tsio_stage_commit moves all of them, or
 * tsio_stage_abort removes all of them with the folders the job created.
 *
 * Every temporary name and created folder is also recorded in a fixed
 * table that a SIGINT/SIGTERM/SIGHUP handler (tsio_cleanup_on_signals) can
 * walk with async-signal-safe calls only (unlink, rmdir, write): the
 * temporary file, its usual sidecars (".aux.xml", "-journal", "-wal",
 * ...), then the folders, newest first.  The handler then dies by the
 * signal as if it had not been caught.
 *
 * This is process state (signals are per process), so it lives here in
 * the front end's I/O layer and never in the core.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cpl_vsi.h>
#include <gdal.h>

#include "tsio_internal.h"

#define STAGE_SLOTS 64
#define STAGE_PATH 4096

/* What the signal handler reads: paths written before `used` is set. */
typedef struct stage_slot {
    volatile sig_atomic_t used; /* 0 free, 1 temporary dataset, 2 created folder */
    char temp[STAGE_PATH];      /* the temporary file (or the folder) */
    char tstem[STAGE_PATH];     /* dir/.stem.tmpPID: sidecars that drop the extension */
} stage_slot;

static stage_slot stage_slots[STAGE_SLOTS];
static pthread_mutex_t stage_lock = PTHREAD_MUTEX_INITIALIZER;

/* What commit moves: a staged dataset (main thread only). */
typedef struct staged {
    out_name name;
    char *path;      /* as the user gave it, for messages */
    int slot;        /* in stage_slots, or -1 */
    int gdal_rename; /* a raster: GDALRenameDataset first */
    int moved;
} staged;

static int stage_active;
static staged *stage_list;
static int stage_n, stage_cap;

static const char *const sidecars[] = {".aux.xml", "-journal", "-wal", "-shm", ".ovr", ".msk",
                                       ".shx",     ".dbf",     ".prj", ".cpg", ".qix", NULL};

static void copy_path(char *dst, const char *src)
{
    size_t n = strlen(src);
    if (n >= STAGE_PATH)
        n = STAGE_PATH - 1;
    memcpy(dst, src, n);
    dst[n] = '\0';
}

/* Block the cleanup signals while the table changes. */
static void stage_mask(sigset_t *old)
{
    sigset_t s;
    sigemptyset(&s);
    sigaddset(&s, SIGINT);
    sigaddset(&s, SIGTERM);
    sigaddset(&s, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &s, old);
    pthread_mutex_lock(&stage_lock);
}

static void stage_unmask(const sigset_t *old)
{
    pthread_mutex_unlock(&stage_lock);
    pthread_sigmask(SIG_SETMASK, old, NULL);
}

static int slot_add(int kind, const char *temp, const char *tstem)
{
    sigset_t old;
    int i, got = -1;
    if (tsio__starts_with(temp, "/vsi"))
        return -1; /* nothing a signal handler can unlink */
    stage_mask(&old);
    for (i = 0; i < STAGE_SLOTS && got < 0; i++)
        if (!stage_slots[i].used) {
            copy_path(stage_slots[i].temp, temp);
            copy_path(stage_slots[i].tstem, tstem ? tstem : "");
            stage_slots[i].used = kind;
            got = i;
        }
    stage_unmask(&old);
    return got;
}

static void slot_free(int slot)
{
    sigset_t old;
    if (slot < 0)
        return;
    stage_mask(&old);
    stage_slots[slot].used = 0;
    stage_unmask(&old);
}

int tsio__temp_register(const out_name *o)
{
    char *tstem =
        tsio__str_fmt("%s%s%s", o->dir, o->dir[0] && strcmp(o->dir, "/") ? "/" : "", o->tstem);
    int slot = slot_add(1, o->temp, tstem ? tstem : "");
    free(tstem);
    return slot;
}

void tsio__temp_unregister(int slot)
{
    slot_free(slot);
}

int tsio__stage_active(void)
{
    return stage_active;
}

int tsio__stage_keep(out_name *o, const char *path, int slot, int gdal_rename, tsio_err *err)
{
    if (stage_n == stage_cap) {
        int cap = stage_cap ? 2 * stage_cap : 8;
        staged *l = realloc(stage_list, (size_t)cap * sizeof *l);
        if (!l) {
            tsio_errf(err, path, "out of memory");
            return -1;
        }
        stage_list = l;
        stage_cap = cap;
    }
    stage_list[stage_n].path = tsio__str_dup(path);
    if (!stage_list[stage_n].path) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    stage_list[stage_n].name = *o; /* ownership moves to the stage */
    memset(o, 0, sizeof *o);
    stage_list[stage_n].slot = slot;
    stage_list[stage_n].gdal_rename = gdal_rename;
    stage_list[stage_n].moved = 0;
    stage_n++;
    return 0;
}

void tsio_stage_begin(void)
{
    stage_active = 1;
}

static void stage_clear(void)
{
    int i;
    for (i = 0; i < stage_n; i++) {
        tsio__out_name_free(&stage_list[i].name);
        free(stage_list[i].path);
    }
    free(stage_list);
    stage_list = NULL;
    stage_n = stage_cap = 0;
    stage_active = 0;
}

/* Remove the folders the job created (newest first; only when empty). */
static void stage_drop_dirs(void)
{
    int i;
    for (i = STAGE_SLOTS - 1; i >= 0; i--)
        if (stage_slots[i].used == 2) {
            rmdir(stage_slots[i].temp);
            slot_free(i);
        }
}

void tsio_stage_abort(void)
{
    int i;
    for (i = 0; i < stage_n; i++) {
        tsio__remove_temp_files(&stage_list[i].name);
        tsio__temp_unregister(stage_list[i].slot);
    }
    stage_drop_dirs();
    stage_clear();
}

int tsio_stage_commit(tsio_err *err)
{
    int i, rc = 0;
    for (i = 0; i < stage_n && rc == 0; i++) {
        staged *s = &stage_list[i];
        rc = tsio__move_into_place(&s->name, s->path, s->gdal_rename, err);
        if (rc == 0) {
            s->moved = 1;
            tsio__temp_unregister(s->slot);
        }
    }
    /* on failure, what is not yet in place is removed (err names the file) */
    for (i = 0; i < stage_n; i++)
        if (!stage_list[i].moved) {
            tsio__remove_temp_files(&stage_list[i].name);
            tsio__temp_unregister(stage_list[i].slot);
        }
    /* the folders the job created stay once it is in place */
    for (i = 0; i < STAGE_SLOTS; i++)
        if (stage_slots[i].used == 2) {
            if (rc != 0)
                rmdir(stage_slots[i].temp);
            slot_free(i);
        }
    stage_clear();
    return rc;
}

int tsio_stage_dir_created(const char *dir)
{
    return slot_add(2, dir, NULL) >= 0 ? 0 : -1;
}

/* ------------------------------------------------------------------ */
/* signals                                                             */
/* ------------------------------------------------------------------ */

static const char *sig_prog = "terrasynth";

static void sig_write(const char *s)
{
    ssize_t r = write(STDERR_FILENO, s, strlen(s));
    (void)r;
}

static void sig_write_int(long v)
{
    char buf[24];
    int n = 0;
    char out[24];
    int k = 0;
    if (v == 0)
        buf[n++] = '0';
    while (v > 0 && n < (int)sizeof buf) {
        buf[n++] = (char)('0' + v % 10);
        v /= 10;
    }
    while (n > 0)
        out[k++] = buf[--n];
    out[k] = '\0';
    sig_write(out);
}

/* unlink that counts; a path built in a fixed buffer */
static int sig_unlink(const char *a, const char *b)
{
    char p[STAGE_PATH + 32];
    size_t na = strlen(a), nb = b ? strlen(b) : 0;
    if (na + nb >= sizeof p)
        return 0;
    memcpy(p, a, na);
    if (nb)
        memcpy(p + na, b, nb);
    p[na + nb] = '\0';
    return unlink(p) == 0;
}

static void sig_cleanup(int sig)
{
    int saved = errno, i, k, files = 0, dirs = 0;
    for (i = 0; i < STAGE_SLOTS; i++) {
        if (stage_slots[i].used != 1)
            continue;
        files += sig_unlink(stage_slots[i].temp, NULL);
        for (k = 0; sidecars[k]; k++) {
            files += sig_unlink(stage_slots[i].temp, sidecars[k]);
            if (stage_slots[i].tstem[0])
                files += sig_unlink(stage_slots[i].tstem, sidecars[k]);
        }
    }
    for (i = STAGE_SLOTS - 1; i >= 0; i--)
        if (stage_slots[i].used == 2 && rmdir(stage_slots[i].temp) == 0)
            dirs++;
    sig_write(sig_prog);
    sig_write(": interrupted: ");
    if (files || dirs) {
        sig_write("removed ");
        sig_write_int(files);
        sig_write(" unfinished output file(s) and ");
        sig_write_int(dirs);
        sig_write(" folder(s) it had created; nothing was written\n");
    } else
        sig_write("nothing was written\n");
    errno = saved;
    signal(sig, SIG_DFL);
    raise(sig);
}

void tsio_cleanup_on_signals(const char *prog)
{
    struct sigaction sa;
    int sigs[3] = {SIGINT, SIGTERM, SIGHUP}, i;
    if (prog)
        sig_prog = prog;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = sig_cleanup;
    sigemptyset(&sa.sa_mask);
    for (i = 0; i < 3; i++)
        sigaddset(&sa.sa_mask, sigs[i]);
    for (i = 0; i < 3; i++) {
        struct sigaction prev;
        /* a signal ignored by the parent (nohup) stays ignored */
        if (sigaction(sigs[i], NULL, &prev) == 0 && prev.sa_handler == SIG_IGN)
            continue;
        sigaction(sigs[i], &sa, NULL);
    }
    /* a file size limit (ulimit -f): the write fails with EFBIG and the job says so and
     * cleans up, instead of dying of SIGXFSZ with its temporary files left */
    signal(SIGXFSZ, SIG_IGN);
}
