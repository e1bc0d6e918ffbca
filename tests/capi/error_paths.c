/* Every error path of rangewalk's C ABI: NULL handles and pointers,
 * missing and invalid files, a bake of another scene, an unfinished bake,
 * zero and overflowing sizes, bad options and a cancelled bake. Each
 * failure must return its status, say why in rw_last_error, and leave the
 * outputs untouched. (The panic boundary is tested in src/capi/error.rs:
 * the library exports no call that panics on purpose.)
 *
 *   error_paths <cornell scene.toml> <other scene.toml> <cornell bake dir> <work dir>
 */

#include <rangewalk.h>

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
/* For limits_and_outputs. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <sys/statvfs.h>
#include <unistd.h>

static int failures = 0;
static int checks = 0;

static const char *last_error(void) {
    static char buf[4096];
    rw_last_error(buf, sizeof buf);
    return buf;
}

/* A call must return `want` and its message must contain `needle`. */
static void expect(rw_status got, rw_status want, const char *needle, const char *what, int line) {
    ++checks;
    const char *message = got == RW_OK ? "" : last_error();
    if (got != want || (needle && !strstr(message, needle))) {
        ++failures;
        fprintf(stderr, "line %d: %s: got %s (%s), want %s with \"%s\"\n", line, what,
                rw_status_name(got), message, rw_status_name(want), needle ? needle : "");
    }
}

#define EXPECT(call, want, needle) expect((call), (want), (needle), #call, __LINE__)
#define CHECK(cond)                                                          \
    do {                                                                     \
        ++checks;                                                            \
        if (!(cond)) {                                                       \
            ++failures;                                                      \
            fprintf(stderr, "line %d: %s does not hold\n", __LINE__, #cond); \
        }                                                                    \
    } while (0)

static int untouched(const float *v, size_t n) {
    for (size_t i = 0; i < n; ++i)
        if (v[i] != -1.0f) return 0;
    return 1;
}

static void fill(float *v, size_t n) {
    for (size_t i = 0; i < n; ++i) v[i] = -1.0f;
}

static bool stop_at_once(void *userdata, float fraction) {
    (void)fraction;
    ++*(int *)userdata;
    return false;
}

static void *fail_in_another_thread(void *arg) {
    (void)arg;
    rw_scene *s = NULL;
    rw_scene_load("/nonexistent/other-thread.toml", &s);
    return NULL;
}

/* Concurrent bakes of one directory: a second run of the images a running
 * bake renders (here from another thread: the lock is per open file, so it
 * keeps threads apart as it does processes) gets RW_BAKE naming the holder;
 * one with other settings is refused naming it too; the first bake ends
 * untouched. */
typedef struct {
    pthread_mutex_t mutex;
    pthread_cond_t cond;
    int paused, go;
    rw_scene *scene;
    rw_bake_options options;
    char dir[1024];
    rw_status status;
} held_bake;

static void held_bake_signal(held_bake *h, int *flag) {
    pthread_mutex_lock(&h->mutex);
    *flag = 1;
    pthread_cond_broadcast(&h->cond);
    pthread_mutex_unlock(&h->mutex);
}

static void held_bake_wait(held_bake *h, const int *flag) {
    pthread_mutex_lock(&h->mutex);
    while (!*flag) pthread_cond_wait(&h->cond, &h->mutex);
    pthread_mutex_unlock(&h->mutex);
}

/* Holds the bake at its first report (planned, registered, no image yet)
 * until told to go on. */
static bool hold_at_start(void *userdata, float fraction) {
    held_bake *h = userdata;
    if (fraction == 0.0f) {
        held_bake_signal(h, &h->paused);
        held_bake_wait(h, &h->go);
    }
    return true;
}

static void *run_held_bake(void *arg) {
    held_bake *h = arg;
    h->status = rw_bake_run(h->scene, &h->options, h->dir, hold_at_start, h);
    held_bake_signal(h, &h->paused); /* a bake that failed early holds no one up */
    return NULL;
}

static void concurrent_bakes(rw_scene *scene, const rw_bake_options *tiny, const char *work) {
    held_bake h = {.scene = scene, .options = *tiny};
    pthread_mutex_init(&h.mutex, NULL);
    pthread_cond_init(&h.cond, NULL);
    snprintf(h.dir, sizeof h.dir, "%s/concurrent", work);
    pthread_t first;
    pthread_create(&first, NULL, run_held_bake, &h);
    held_bake_wait(&h, &h.paused);
    EXPECT(rw_bake_run(scene, tiny, h.dir, NULL, NULL), RW_BAKE, "in use");
    CHECK(strstr(last_error(), "(this process)") != NULL);
    rw_bake_options other = *tiny;
    other.spp = tiny->spp + 1;
    EXPECT(rw_bake_run(scene, &other, h.dir, NULL, NULL), RW_BAKE, "other settings");
    CHECK(strstr(last_error(), "being baked now by process") != NULL);
    held_bake_signal(&h, &h.go);
    pthread_join(first, NULL);
    CHECK(h.status == RW_OK);
    rw_bake *bake = NULL;
    EXPECT(rw_bake_open(h.dir, &bake), RW_OK, NULL);
    rw_bake_free(bake);
    pthread_cond_destroy(&h.cond);
    pthread_mutex_destroy(&h.mutex);
}
/* End of concurrent bakes. */

/* ---- Limits of work and outputs that cannot be written ------------------
 * Counts that set the work of a pixel are bounded (light rays per side of
 * a rim pixel, re-shading samples, a frame's subpixels), whatever the
 * caller sets; a bake into a folder that cannot be made, or onto a full
 * disk, fails with RW_IO naming the file and leaves no file under a final
 * name that is not whole. The full disk is the tmpfs the Makefile mounts
 * at $RW_FULL_DIR (capi-test); without it this test fails. */

/* Fills the file system of `dir` until at most `leave` bytes are free,
 * with a file `filler` in it; returns 0 on success. */
static int fill_disk(const char *dir, unsigned long long leave) {
    char path[1024];
    snprintf(path, sizeof path, "%s/filler", dir);
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) return -1;
    static char block[4096];
    for (;;) {
        struct statvfs vfs;
        if (fstatvfs(fd, &vfs) != 0) break;
        if ((unsigned long long)vfs.f_bavail * vfs.f_bsize <= leave) break;
        if (write(fd, block, sizeof block) != (ssize_t)sizeof block) break; /* ENOSPC */
    }
    close(fd);
    return 0;
}

/* Whether every file under `dir` (recursively) is whole as far as a name
 * tells: no empty file under a final name, and no temporary left. */
static int nothing_half_written(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return errno == ENOENT;
    int ok = 1;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        char path[2048];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (stat(path, &st) != 0) continue;
        if (S_ISDIR(st.st_mode)) {
            ok &= nothing_half_written(path);
        } else if (strstr(e->d_name, ".partial") || (e->d_name[0] != '.' && st.st_size == 0)) {
            fprintf(stderr, "left behind: %s (%lld bytes)\n", path, (long long)st.st_size);
            ok = 0;
        }
    }
    closedir(d);
    return ok;
}

static void limits_and_outputs(rw_scene *scene, rw_bake *bake, const rw_view *view,
                               const rw_bake_options *tiny) {
    enum { W = 8, H = 6 };
    float rgb[W * H * 3];
    fill(rgb, W * H * 3);
    rw_synth_options defaults, so;
    EXPECT(rw_synth_options_default(&defaults), RW_OK, NULL);
    so = defaults;
    so.light_rays = 100000;
    EXPECT(rw_synth_with(bake, view, 0.5f, W, H, &so, rgb, NULL), RW_INVALID_ARGUMENT,
           "options->light_rays 100000 must lie in 0..=32");
    so.light_rays = 33;
    EXPECT(rw_synth_with(bake, view, 0.5f, W, H, &so, rgb, NULL), RW_INVALID_ARGUMENT,
           "options->light_rays 33");
    so = defaults;
    so.reshade_samples = 257;
    EXPECT(rw_synth_with(bake, view, 0.5f, W, H, &so, rgb, NULL), RW_INVALID_ARGUMENT,
           "options->reshade_samples 257 must lie in 1..=256");
    so = defaults;
    so.supersample = 0;
    EXPECT(rw_synth_with(bake, view, 0.5f, W, H, &so, rgb, NULL), RW_INVALID_ARGUMENT,
           "options->supersample 0");
    /* 8192 x 8192 is within the sides a frame may have, but at the
     * default 2 x 2 subpixels it is 268 M of them (12.9 GB of z-buffer). */
    EXPECT(rw_synth_with(bake, view, 0.5f, 8192, 8192, &defaults, rgb, NULL), RW_INVALID_ARGUMENT,
           "268435456 subpixels");
    CHECK(untouched(rgb, W * H * 3));
    /* The largest counts allowed make a frame. */
    so = defaults;
    so.light_rays = 32;
    so.reshade_samples = 256;
    so.time_interp = RW_TIME_INTERP_RESHADE;
    EXPECT(rw_synth_with(bake, view, 0.5f, W, H, &so, rgb, NULL), RW_OK, NULL);
    CHECK(!untouched(rgb, W * H * 3));

    /* A folder that cannot be made. */
    const char *proc = "/proc/rangewalk-bake";
    EXPECT(rw_bake_run(scene, tiny, proc, NULL, NULL), RW_IO, proc);
    struct stat st;
    CHECK(stat(proc, &st) != 0);

    /* A full disk, then ones with room for a few pages only (the images
     * are a page each, no radiosity store is written): whichever file the
     * space runs out in, the error names a file under the bake and nothing
     * half written remains. */
    const char *full = getenv("RW_FULL_DIR");
    CHECK(full != NULL && *full);
    if (!full || !*full) {
        fprintf(stderr, "RW_FULL_DIR is not set: run this test through `make capi-test`\n");
        return;
    }
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/bake", full);
    rw_bake_options traced = *tiny;
    traced.indirect = RW_INDIRECT_PATH;
    for (unsigned long long leave = 0; leave <= 24 * 1024; leave += 4 * 1024) {
        CHECK(fill_disk(full, leave) == 0);
        EXPECT(rw_bake_run(scene, &traced, dir, NULL, NULL), RW_IO, dir);
        CHECK(strstr(last_error(), "space left") != NULL);
        CHECK(nothing_half_written(full));
        rw_bake *opened = NULL;
        CHECK(rw_bake_open(dir, &opened) != RW_OK && opened == NULL);
        char cmd[2200];
        snprintf(cmd, sizeof cmd, "rm -rf '%s' '%s/filler'", dir, full);
        CHECK(system(cmd) == 0);
    }
}
/* ---- end of limits and outputs ---- */

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: %s <cornell scene> <other scene> <cornell bake> <work dir>\n", argv[0]);
        return 2;
    }
    const char *cornell_path = argv[1], *other_path = argv[2], *bake_dir = argv[3], *work = argv[4];
    mkdir(work, 0755);

    /* Static strings, and no message before any failure. */
    CHECK(strlen(rw_version()) > 0);
    CHECK(strcmp(rw_status_name(RW_CANCELLED), "RW_CANCELLED") == 0);
    CHECK(strcmp(rw_status_name(99), "RW_UNKNOWN") == 0);
    CHECK(rw_last_error(NULL, 0) == 0);

    /* Scenes. */
    rw_scene *const sentinel = (rw_scene *)(uintptr_t)0x1;
    rw_scene *scene = sentinel;
    EXPECT(rw_scene_load(NULL, &scene), RW_INVALID_ARGUMENT, "`path` is NULL");
    EXPECT(rw_scene_load(cornell_path, NULL), RW_INVALID_ARGUMENT, "`out` is NULL");
    EXPECT(rw_scene_load("", &scene), RW_INVALID_ARGUMENT, "empty");
    EXPECT(rw_scene_load("/nonexistent/scene.toml", &scene), RW_IO, "/nonexistent/scene.toml");
    char bad[1024];
    snprintf(bad, sizeof bad, "%s/bad.toml", work);
    FILE *f = fopen(bad, "w");
    fputs("[animation]\nstart = \"soon\"\n", f);
    fclose(f);
    EXPECT(rw_scene_load(bad, &scene), RW_SCENE, "bad.toml");
    CHECK(scene == sentinel);
    rw_scene_free(NULL);

    /* Messages are per thread, and cut to the caller's buffer. */
    pthread_t other_thread;
    pthread_create(&other_thread, NULL, fail_in_another_thread, NULL);
    pthread_join(other_thread, NULL);
    CHECK(strstr(last_error(), "bad.toml") != NULL);
    char small[8];
    size_t full = rw_last_error(small, sizeof small);
    CHECK(full > sizeof small && strlen(small) == sizeof small - 1);
    CHECK(rw_last_error(small, 0) == full);

    EXPECT(rw_scene_load(cornell_path, &scene), RW_OK, NULL);
    rw_scene *other = NULL;
    EXPECT(rw_scene_load(other_path, &other), RW_OK, NULL);

    /* Views. */
    rw_view view, kept;
    memset(&kept, 0x55, sizeof kept);
    view = kept;
    EXPECT(rw_scene_camera(NULL, "main", &view), RW_INVALID_ARGUMENT, "`scene` is NULL");
    EXPECT(rw_scene_camera(scene, NULL, &view), RW_INVALID_ARGUMENT, "`name` is NULL");
    EXPECT(rw_scene_camera(scene, "main", NULL), RW_INVALID_ARGUMENT, "`out` is NULL");
    EXPECT(rw_scene_camera(scene, "nowhere", &view), RW_INVALID_ARGUMENT, "nowhere");
    EXPECT(rw_scene_path_view(scene, "nowhere", 0.5f, &view), RW_INVALID_ARGUMENT, "nowhere");
    EXPECT(rw_scene_path_view(scene, "walk", NAN, &view), RW_INVALID_ARGUMENT, "time");
    CHECK(memcmp(&view, &kept, sizeof view) == 0);
    EXPECT(rw_scene_camera(scene, "main", &view), RW_OK, NULL);

    /* Rendering: every argument checked, the output untouched on failure. */
    enum { W = 8, H = 6 };
    float rgb[W * H * 3], distance[W * H];
    fill(rgb, W * H * 3);
    EXPECT(rw_render(NULL, &view, 0, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "`scene` is NULL");
    EXPECT(rw_render(scene, NULL, 0, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "`view` is NULL");
    EXPECT(rw_render(scene, &view, 0, W, H, 1, 0, NULL), RW_INVALID_ARGUMENT, "`rgb` is NULL");
    EXPECT(rw_render(scene, &view, 0, 0, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "no pixels");
    EXPECT(rw_render(scene, &view, 0, W, 0, 1, 0, rgb), RW_INVALID_ARGUMENT, "no pixels");
    EXPECT(rw_render(scene, &view, 0, UINT32_MAX, UINT32_MAX, 1, 0, rgb), RW_INVALID_ARGUMENT, "exceeds");
    EXPECT(rw_render(scene, &view, 0, W, H, 0, 0, rgb), RW_INVALID_ARGUMENT, "spp");
    EXPECT(rw_render(scene, &view, INFINITY, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "time");
    rw_view bad_view = view;
    bad_view.vfov_degrees = 0;
    EXPECT(rw_render(scene, &bad_view, 0, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "vfov_degrees");
    bad_view = view;
    memcpy(bad_view.look_at, bad_view.position, sizeof bad_view.position);
    EXPECT(rw_render(scene, &bad_view, 0, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "no length");
    bad_view = view;
    bad_view.position[1] = NAN;
    EXPECT(rw_render(scene, &bad_view, 0, W, H, 1, 0, rgb), RW_INVALID_ARGUMENT, "position");
    CHECK(untouched(rgb, W * H * 3));
    EXPECT(rw_render(scene, &view, 0, W, H, 1, 0, rgb), RW_OK, NULL);
    CHECK(!untouched(rgb, W * H * 3));

    /* Bake options. */
    EXPECT(rw_bake_options_default(NULL), RW_INVALID_ARGUMENT, "`options` is NULL");
    rw_bake_options options;
    EXPECT(rw_bake_options_default(&options), RW_OK, NULL);
    CHECK(options.struct_size == sizeof options && options.spp == 16 && options.quality == 0.5f);
    CHECK(options.noise == 0.02f && options.max_spp == 0);
    char fresh[1024];
    snprintf(fresh, sizeof fresh, "%s/never-made", work);
    rw_bake_options o = options;
    o.quality = 2;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "quality");
    o = options;
    o.projection = 9;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "projection");
    o = options;
    o.indirect = 9;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "indirect");
    o = options;
    o.noise = -0.5f;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "options->noise -0.5");
    o.noise = NAN;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "options->noise NaN");
    o = options;
    o.max_spp = options.spp - 1;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT,
           "options->max_spp 15 is below options->spp 16");
    /* The library's checks name the C fields, never a command-line flag. */
    CHECK(!strstr(last_error(), "--"));
    o = options;
    o.size = 7;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT,
           "options->size 7 is below the smallest base image side");
    CHECK(strstr(last_error(), "options->frame_width, frame_height") && !strstr(last_error(), "--"));
    o = options;
    o.shard_index = 3;
    o.shard_count = 2;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "shard_index");
    o = options;
    o.struct_size = 0;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "struct_size");
    o.struct_size = sizeof o + 8;
    EXPECT(rw_bake_run(scene, &o, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "struct_size");
    EXPECT(rw_bake_run(NULL, &options, fresh, NULL, NULL), RW_INVALID_ARGUMENT, "`scene` is NULL");
    EXPECT(rw_bake_run(scene, &options, NULL, NULL, NULL), RW_INVALID_ARGUMENT, "`dir` is NULL");
    struct stat st;
    CHECK(stat(fresh, &st) != 0);

    /* A bake of another scene is refused, to run and to open. */
    rw_bake *bake = (rw_bake *)(uintptr_t)0x1;
    EXPECT(rw_bake_run(other, &options, bake_dir, NULL, NULL), RW_BAKE, "differs");
    EXPECT(rw_bake_open_with_scene(other, bake_dir, &bake), RW_BAKE, "differs");
    EXPECT(rw_bake_open(NULL, &bake), RW_INVALID_ARGUMENT, "`dir` is NULL");
    EXPECT(rw_bake_open(bake_dir, NULL), RW_INVALID_ARGUMENT, "`out` is NULL");
    EXPECT(rw_bake_open("/nonexistent/bake", &bake), RW_IO, "/nonexistent/bake");
    EXPECT(rw_bake_open(work, &bake), RW_IO, "manifest.json");
    CHECK(bake == (rw_bake *)(uintptr_t)0x1);
    rw_bake_free(NULL);

    /* A cancelled bake stops, cannot be opened, and resumes to completion. */
    char cancelled[1024];
    snprintf(cancelled, sizeof cancelled, "%s/cancelled", work);
    rw_bake_options tiny = options;
    tiny.quality = 0.1f;
    tiny.size = 16;
    tiny.spp = 1;
    int calls = 0;
    EXPECT(rw_bake_run(scene, &tiny, cancelled, stop_at_once, &calls), RW_CANCELLED, "cancelled");
    CHECK(calls == 1);
    EXPECT(rw_bake_open(cancelled, &bake), RW_BAKE, "not complete");
    tiny.spp = 2;
    EXPECT(rw_bake_run(scene, &tiny, cancelled, NULL, NULL), RW_BAKE, "other settings");
    tiny.spp = 1;
    EXPECT(rw_bake_run(scene, &tiny, cancelled, NULL, NULL), RW_OK, NULL);
    EXPECT(rw_bake_open(cancelled, &bake), RW_OK, NULL);
    rw_bake_free(bake);
    concurrent_bakes(scene, &tiny, work);

    /* Synthesis. */
    EXPECT(rw_bake_open_with_scene(scene, bake_dir, &bake), RW_OK, NULL);

    /* The plan. */
    size_t views = 0, time_count = 0;
    float position[3] = {-1, -1, -1}, times[2] = {-1, -1};
    EXPECT(rw_bake_view_count(NULL, &views), RW_INVALID_ARGUMENT, "`bake` is NULL");
    EXPECT(rw_bake_view_count(bake, NULL), RW_INVALID_ARGUMENT, "`count` is NULL");
    EXPECT(rw_bake_view_count(bake, &views), RW_OK, NULL);
    CHECK(views >= 2);
    EXPECT(rw_bake_view(bake, views, position, times, 2, &time_count), RW_INVALID_ARGUMENT, "not below");
    EXPECT(rw_bake_view(bake, 0, NULL, times, 2, &time_count), RW_INVALID_ARGUMENT, "`position` is NULL");
    EXPECT(rw_bake_view(bake, 0, position, times, 2, NULL), RW_INVALID_ARGUMENT, "`time_count` is NULL");
    CHECK(untouched(position, 3) && untouched(times, 2) && time_count == 0);
    EXPECT(rw_bake_view(bake, 0, position, NULL, 0, &time_count), RW_OK, NULL);
    CHECK(time_count >= 1 && position[1] == 273.0f);
    EXPECT(rw_bake_view(bake, 0, position, times, 1, &time_count), RW_OK, NULL);
    CHECK(times[0] == 0.0f && times[1] == -1.0f);
    rw_scene_free(other);
    fill(rgb, W * H * 3);
    fill(distance, W * H);
    EXPECT(rw_synth(NULL, &view, 0.5f, W, H, rgb, distance), RW_INVALID_ARGUMENT, "`bake` is NULL");
    EXPECT(rw_synth(bake, NULL, 0.5f, W, H, rgb, distance), RW_INVALID_ARGUMENT, "`view` is NULL");
    EXPECT(rw_synth(bake, &view, 0.5f, W, H, NULL, distance), RW_INVALID_ARGUMENT, "`rgb` is NULL");
    EXPECT(rw_synth(bake, &view, 0.5f, 0, H, rgb, distance), RW_INVALID_ARGUMENT, "no pixels");
    EXPECT(rw_synth(bake, &view, 0.5f, 1u << 20, 1u << 20, rgb, distance), RW_INVALID_ARGUMENT, "exceeds");
    EXPECT(rw_synth(bake, &view, NAN, W, H, rgb, distance), RW_INVALID_ARGUMENT, "time");
    EXPECT(rw_synth_options_default(NULL), RW_INVALID_ARGUMENT, "`options` is NULL");
    rw_synth_options synth_defaults, so;
    EXPECT(rw_synth_options_default(&synth_defaults), RW_OK, NULL);
    CHECK(synth_defaults.bases == 4 && synth_defaults.fill == RW_FILL_BOTH &&
          synth_defaults.time_interp == RW_TIME_INTERP_RESHADE && synth_defaults.filter == RW_FILTER_BOX);
    so = synth_defaults;
    so.bases = 0;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "bases");
    so = synth_defaults;
    so.fill = 7;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "fill");
    so = synth_defaults;
    so.time_interp = 7;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "time_interp");
    so = synth_defaults;
    so.blend = 7;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "blend");
    so = synth_defaults;
    so.filter = 2;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "filter");
    so = synth_defaults;
    so.tolerance = 1.5f;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "tolerance");
    so = synth_defaults;
    so.fill_reach = 70000;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "fill_reach");
    so = synth_defaults;
    so.reshade_samples = 0;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "reshade_samples");
    so = synth_defaults;
    so.base_memory_mib = UINT64_MAX;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, distance), RW_INVALID_ARGUMENT, "base_memory_mib");
    CHECK(untouched(rgb, W * H * 3) && untouched(distance, W * H));
    /* An older header's smaller struct: the rest keeps the defaults. */
    so = synth_defaults;
    so.struct_size = 8;
    EXPECT(rw_synth_with(bake, &view, 0.5f, W, H, &so, rgb, NULL), RW_OK, NULL);
    CHECK(!untouched(rgb, W * H * 3) && untouched(distance, W * H));
    limits_and_outputs(scene, bake, &view, &tiny);
    rw_bake_free(bake);

    rw_scene_free(scene);

    printf("error_paths: %d checks, %d failed\n", checks, failures);
    return failures ? 1 : 0;
}
