/* AprilTag C library (Debian libapriltag-dev, AprilTag 3) on 8-bit PGM frames: per-frame
 * detection time and the detections, for pa-track's examples/apriltag_compare.rs.
 *
 *   ./apriltag_bench DECIMATE THREADS REPS OUT.txt frame_000.pgm frame_001.pgm ...
 *
 * Each frame is detected REPS times after one warm-up detection of the first frame; every
 * run is timed (CLOCK_MONOTONIC around apriltag_detector_detect only; the image is loaded
 * before). OUT gets "T frame ms" per run and "D frame id hamming margin p0x p0y .. p3x p3y"
 * per detection of the last run (the library's corner order and +0.5 px pixel convention).
 * Settings: tag36h11, quad_decimate = DECIMATE, nthreads = THREADS, the library's defaults
 * otherwise (quad_sigma 0, refine_edges 1, decode_sharpening 0.25, max_hamming 2). Prints
 * the median and p95 per frame to stdout. Not part of CI (see ../README.md). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdint.h>
#include <time.h>
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <apriltag/common/image_u8.h>

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* An 8-bit binary PGM (P5, maxval 255, no comments) as an image_u8_t (the library's own
 * loader is not exported by Debian's libapriltag.so). */
static image_u8_t *read_pgm(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    int w, h, maxval;
    if (fscanf(f, "P5 %d %d %d", &w, &h, &maxval) != 3 || maxval != 255 || w <= 0 || h <= 0 ||
        fgetc(f) == EOF) {
        fclose(f);
        return NULL;
    }
    image_u8_t *im = malloc(sizeof(image_u8_t));
    uint8_t *buf = malloc((size_t)w * (size_t)h);
    image_u8_t tmp = {.width = w, .height = h, .stride = w, .buf = buf};
    memcpy(im, &tmp, sizeof tmp);
    size_t got = fread(buf, 1, (size_t)w * (size_t)h, f);
    fclose(f);
    if (got != (size_t)w * (size_t)h) {
        free(buf);
        free(im);
        return NULL;
    }
    return im;
}

static void free_pgm(image_u8_t *im) {
    free(im->buf);
    free(im);
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s DECIMATE THREADS REPS OUT.txt FRAME.pgm...\n", argv[0]);
        return 2;
    }
    float decimate = (float)atof(argv[1]);
    int threads = atoi(argv[2]);
    int reps = atoi(argv[3]);
    FILE *out = fopen(argv[4], "w");
    if (!out) {
        fprintf(stderr, "%s: cannot write\n", argv[4]);
        return 1;
    }
    int n = argc - 5;
    apriltag_family_t *tf = tag36h11_create();
    apriltag_detector_t *td = apriltag_detector_create();
    apriltag_detector_add_family_bits(td, tf, 2);
    td->quad_decimate = decimate;
    td->nthreads = threads;
    /* APRILTAG_MIN_WB_DIFF: the binarisation's min_white_black_diff (library default 5;
     * pa-track's default is 20), to separate that setting from the implementations. */
    const char *wb = getenv("APRILTAG_MIN_WB_DIFF");
    if (wb) td->qtp.min_white_black_diff = atoi(wb);
    double *times = malloc(sizeof(double) * (size_t)n * (size_t)reps);
    int nt = 0;
    for (int f = 0; f < n; f++) {
        image_u8_t *im = read_pgm(argv[5 + f]);
        if (!im) {
            fprintf(stderr, "%s: cannot read as an 8-bit PGM\n", argv[5 + f]);
            return 1;
        }
        if (f == 0) {
            zarray_t *w = apriltag_detector_detect(td, im);
            apriltag_detections_destroy(w);
        }
        for (int r = 0; r < reps; r++) {
            double t0 = now_ms();
            zarray_t *dets = apriltag_detector_detect(td, im);
            double t = now_ms() - t0;
            times[nt++] = t;
            fprintf(out, "T %d %.4f\n", f, t);
            if (r == reps - 1) {
                for (int i = 0; i < zarray_size(dets); i++) {
                    apriltag_detection_t *d;
                    zarray_get(dets, i, &d);
                    fprintf(out, "D %d %d %d %.4f", f, d->id, d->hamming, d->decision_margin);
                    for (int k = 0; k < 4; k++)
                        fprintf(out, " %.6f %.6f", d->p[k][0], d->p[k][1]);
                    fprintf(out, "\n");
                }
            }
            apriltag_detections_destroy(dets);
        }
        free_pgm(im);
    }
    qsort(times, (size_t)nt, sizeof(double), cmp);
    printf("decimate %g, %d threads, min_white_black_diff %d: %d runs, median %.3f ms, p95 %.3f ms\n", decimate, threads,
           td->qtp.min_white_black_diff, nt, times[(nt - 1) / 2], times[(int)((nt - 1) * 0.95 + 0.5)]);
    fclose(out);
    free(times);
    apriltag_detector_destroy(td);
    tag36h11_destroy(tf);
    return 0;
}
