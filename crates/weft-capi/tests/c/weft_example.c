/* weft_example.c: a host driving Weft through its C ABI, using every call of weft.h.
 *
 * usage: weft_example GRAPH.json OUT.bin
 *
 * Loads GRAPH (tests/c/host_scene.json), lists it, feeds the host's data (a box that rises
 * 1 cm a frame, two strands, a number), pulls frames 1..FRAMES of the scene and writes the
 * cloth's and the hair's positions at each frame to OUT.bin as raw little-endian doubles,
 * for tests/c_program.rs to compare bit for bit with the engine driven from Rust. Every
 * failure path a host meets is exercised too: a graph file with errors, a bad parameter, a
 * mesh with an index out of range, a NaN, a too-small buffer, an interrupted pull. Exits 0
 * when every check holds, 1 (with a message) otherwise. */
#include "weft.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FRAMES 4

static int failures = 0;

#define CHECK(cond)                                                              \
    do {                                                                         \
        if (!(cond)) {                                                           \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
            failures++;                                                          \
        }                                                                        \
    } while (0)

/* String equality that is false, not undefined, when a call returned NULL. */
static int eq(const char *a, const char *b) { return a != NULL && b != NULL && strcmp(a, b) == 0; }

/* Prints an error with all its problems, then frees it. */
static void report(const char *what, WeftError *e) {
    char message[512];
    weft_error_message(e, message, sizeof message);
    fprintf(stderr, "%s: status %d: %s\n", what, (int)weft_error_status(e), message);
    for (size_t i = 0; i < weft_error_problem_count(e); i++) {
        char text[256], node[64], field[64];
        int64_t column = 0;
        int64_t line = weft_error_problem_line(e, i, &column);
        weft_error_problem_text(e, i, WEFT_PROBLEM_MESSAGE, text, sizeof text);
        weft_error_problem_text(e, i, WEFT_PROBLEM_NODE, node, sizeof node);
        weft_error_problem_text(e, i, WEFT_PROBLEM_FIELD, field, sizeof field);
        fprintf(stderr, "  line %lld:%lld node '%s' %s: %s\n", (long long)line,
                (long long)column, node, field, text);
    }
    weft_error_free(e);
}

/* The box the host animates: 8 corners of a 0.2 m cube centred at (0, 0.1 + 0.01 f, 0),
 * computed with + and * only so that Rust computes the same bits. */
static void box_at(int64_t frame, double *xyz, uint32_t *tris) {
    /* corner k has x, y, z at + where bits 0, 1, 2 of k are set; faces wound outward */
    static const uint32_t faces[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                       2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    double y = 0.1 + 0.01 * (double)frame;
    for (int k = 0; k < 8; k++) {
        xyz[3 * k + 0] = (k & 1) ? 0.1 : -0.1;
        xyz[3 * k + 1] = y + ((k & 2) ? 0.1 : -0.1);
        xyz[3 * k + 2] = (k & 4) ? 0.1 : -0.1;
    }
    memcpy(tris, faces, sizeof faces);
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s GRAPH.json OUT.bin\n", argv[0]);
        return 2;
    }
    if (weft_abi_version() != WEFT_ABI_VERSION) {
        fprintf(stderr, "weft.h is ABI %u but the library is %u\n", WEFT_ABI_VERSION,
                weft_abi_version());
        return 1;
    }
    printf("Weft %s, ABI %u\n", weft_version(), weft_abi_version());

    /* A graph file with two errors: every one comes back, with node, field and line. */
    WeftError *err = NULL;
    const char *bad = "{\"format\": \"weft-graph\", \"version\": 1,\n"
                      " \"nodes\": {\"a\": {\"type\": \"value.float\", \"params\": {\"value\": \"x\"}},\n"
                      "           \"b\": {\"type\": \"no.such\"}},\n"
                      " \"outputs\": {\"y\": \"a.out\"}}";
    WeftGraph *broken = weft_graph_load_string(bad, "broken.json", &err);
    CHECK(broken == NULL);
    CHECK(weft_error_status(err) == WEFT_LOAD_FAILED);
    CHECK(weft_error_problem_count(err) == 2);
    int saw_param = 0;
    for (size_t i = 0; i < weft_error_problem_count(err); i++) {
        char node[16], field[32];
        weft_error_problem_text(err, i, WEFT_PROBLEM_NODE, node, sizeof node);
        weft_error_problem_text(err, i, WEFT_PROBLEM_FIELD, field, sizeof field);
        if (strcmp(node, "a") == 0 && strstr(field, "value") != NULL) {
            saw_param = 1;
            CHECK(weft_error_problem_line(err, i, NULL) == 2);
        }
    }
    CHECK(saw_param);
    /* snprintf convention: a size query, then a truncated copy. */
    size_t need = weft_error_message(err, NULL, 0);
    char small[8];
    CHECK(weft_error_message(err, small, sizeof small) == need && strlen(small) == 7);
    weft_error_free(err);
    err = NULL;

    WeftGraph *g = weft_graph_load_file(argv[1], &err);
    if (g == NULL) {
        report("load", err);
        return 1;
    }

    /* Listing: nodes, their ports and parameters, and the graph's outputs. */
    size_t nodes = weft_graph_node_count(g);
    CHECK(nodes > 10);
    int64_t grid = weft_graph_node_index(g, "grid");
    CHECK(grid >= 0 && eq(weft_graph_node_id(g, (size_t)grid), "grid"));
    CHECK(eq(weft_graph_node_type(g, (size_t)grid), "geo.grid"));
    CHECK(weft_graph_node_index(g, "nope") == -1);
    CHECK(weft_graph_node_id(g, nodes) == NULL);
    CHECK(weft_graph_port_count(g, (size_t)grid, WEFT_INPUT) == 0);
    CHECK(weft_graph_port_count(g, (size_t)grid, WEFT_OUTPUT) == 1);
    CHECK(weft_graph_port_count(g, (size_t)grid, 7) == 0); /* an unknown direction: none */
    CHECK(eq(weft_graph_port_name(g, (size_t)grid, WEFT_OUTPUT, 0), "mesh"));
    CHECK(eq(weft_graph_port_type(g, (size_t)grid, WEFT_OUTPUT, 0), "mesh"));
    int64_t solve = weft_graph_node_index(g, "solve");
    CHECK(solve >= 0 && eq(weft_graph_port_type(g, (size_t)solve, WEFT_INPUT, 0), "element"));
    size_t params = weft_graph_param_count(g, (size_t)grid);
    int found_nx = 0;
    for (size_t p = 0; p < params; p++) {
        if (eq(weft_graph_param_name(g, (size_t)grid, p), "nx")) {
            found_nx = 1;
            CHECK(eq(weft_graph_param_kind(g, (size_t)grid, p), "int"));
            char json[512];
            size_t n = weft_graph_param_json(g, (size_t)grid, p, json, sizeof json);
            CHECK(n < sizeof json && strstr(json, "\"value\":5") != NULL);
        }
    }
    CHECK(found_nx);
    size_t outputs = weft_graph_output_count(g);
    CHECK(outputs == 4);
    for (size_t o = 0; o < outputs; o++)
        printf("output %s: %s\n", weft_graph_output_name(g, o), weft_graph_output_type(g, o));
    CHECK(weft_graph_output_name(g, outputs) == NULL && weft_graph_output_type(g, outputs) == NULL);

    /* Parameters: a float, JSON, and two refusals that change nothing. */
    CHECK(weft_graph_set_param_f64(g, "damping", "coefficient", 0.2, NULL) == WEFT_OK);
    CHECK(weft_graph_set_param_json(g, "solve", "substeps", "2", NULL) == WEFT_OK);
    CHECK(weft_graph_set_param_f64(g, "damping", "coefficient", -1.0, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_set_param_json(g, "damping", "nope", "1", &err) == WEFT_NOT_FOUND);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_set_param_json(g, "damping", "coefficient", "{oops", &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_set_output_root(g, NULL, NULL) == WEFT_OK);

    /* Host data: the box, frame by frame; the strands and a number for all frames. */
    double xyz[24];
    uint32_t tris[36];
    for (int64_t f = 0; f <= FRAMES; f++) {
        box_at(f, xyz, tris);
        WeftStatus s = weft_graph_feed_mesh(g, "boxmesh", "mesh", f, xyz, 8, tris, 12, &err);
        if (s != WEFT_OK) {
            report("feed box", err);
            return 1;
        }
    }
    double strands[2 * 5 * 3];
    for (int c = 0; c < 2; c++)
        for (int k = 0; k < 5; k++) {
            strands[15 * c + 3 * k + 0] = c == 0 ? -0.05 : 0.05;
            strands[15 * c + 3 * k + 1] = 0.6 - 0.025 * (double)k;
            strands[15 * c + 3 * k + 2] = 0.025 * (double)k;
        }
    uint32_t offsets[3] = {0, 5, 10};
    CHECK(weft_graph_feed_curves(g, "tuft", "curves", WEFT_ALL_FRAMES, strands, 10, offsets, 2, NULL) == WEFT_OK);
    CHECK(weft_graph_feed_f64(g, "gain", "out", WEFT_ALL_FRAMES, 2.5, NULL) == WEFT_OK);
    /* Refusals: an index out of range, a NaN, a wrong type, a solver's output, bad offsets. */
    uint32_t bad_tri[3] = {0, 1, 8};
    CHECK(weft_graph_feed_mesh(g, "boxmesh", "mesh", 0, xyz, 8, bad_tri, 1, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    double nan_xyz[24];
    memcpy(nan_xyz, xyz, sizeof nan_xyz);
    nan_xyz[4] = NAN;
    CHECK(weft_graph_feed_mesh(g, "boxmesh", "mesh", 0, nan_xyz, 8, tris, 12, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_feed_mesh(g, "gain", "out", 0, xyz, 8, tris, 12, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_feed_f64(g, "solve", "scene", 0, 1.0, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    uint32_t huge_offsets[3] = {0, 0xFFFFFFFFu, 10}; /* must not wrap around */
    CHECK(weft_graph_feed_curves(g, "tuft", "curves", 0, strands, 10, huge_offsets, 2, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    uint32_t bad_offsets[3] = {0, 1, 10};
    CHECK(weft_graph_feed_curves(g, "tuft", "curves", 0, strands, 10, bad_offsets, 2, &err) == WEFT_REJECTED);
    weft_error_free(err);
    err = NULL;
    CHECK(weft_graph_feed_mesh(NULL, "boxmesh", "mesh", 0, xyz, 8, tris, 12, &err) == WEFT_INVALID_ARGUMENT);
    weft_error_free(err);
    err = NULL;
    int64_t fed[8];
    size_t fed_len = 0;
    CHECK(weft_graph_fed_frames(g, "boxmesh", "mesh", fed, 8, &fed_len, NULL) == WEFT_OK);
    CHECK(fed_len == FRAMES + 1 && fed[0] == 0 && fed[FRAMES] == FRAMES);
    CHECK(weft_graph_fed_frames(g, "grid", "mesh", NULL, 0, &fed_len, NULL) == WEFT_NOT_FOUND);

    /* Fed values come back as fed. */
    WeftValue *gain = weft_graph_pull(g, "gain", 0, 0.0, NULL);
    double k = 0.0;
    size_t len = 0;
    CHECK(gain != NULL && eq(weft_value_type(gain), "float"));
    CHECK(weft_value_f64s(gain, &k, 1, &len, NULL) == WEFT_OK && len == 1 && k == 2.5);
    weft_value_free(gain);
    WeftValue *curves = weft_graph_pull_port(g, "tuft", "curves", 0, 0.0, NULL);
    double back[30];
    CHECK(weft_value_f64s(curves, back, 30, &len, NULL) == WEFT_OK && len == 30);
    CHECK(memcmp(back, strands, sizeof back) == 0);
    char summary[128];
    CHECK(weft_value_json(curves, summary, sizeof summary) > 0 && strstr(summary, "\"curves\":2") != NULL);
    weft_value_free(curves);
    CHECK(weft_graph_unfeed(g, "gain", "out", NULL) == WEFT_OK);
    gain = weft_graph_pull(g, "gain", 0, 0.0, NULL);
    CHECK(weft_value_f64s(gain, &k, 1, &len, NULL) == WEFT_OK && k == 1.0);
    weft_value_free(gain);

    /* An interrupted pull stops with its own status; after a reset the graph runs again. */
    WeftInterrupt *stop = weft_graph_interrupter(g);
    weft_interrupt_set(stop);
    WeftValue *none = weft_graph_pull(g, "scene", 1, 24.0, &err);
    CHECK(none == NULL && weft_error_status(err) == WEFT_INTERRUPTED);
    weft_error_free(err);
    err = NULL;
    weft_interrupt_reset(stop);
    weft_interrupt_free(stop);
    CHECK(weft_graph_pull(g, "nope", 1, 24.0, &err) == NULL && weft_error_status(err) == WEFT_NOT_FOUND);
    weft_error_free(err);
    err = NULL;

    /* Bake: pull each frame's scene and copy the cloth's and the hair's positions out. */
    FILE *out = fopen(argv[2], "wb");
    if (out == NULL) {
        perror(argv[2]);
        return 1;
    }
    for (int64_t f = 1; f <= FRAMES; f++) {
        WeftValue *scene = weft_graph_pull(g, "scene", f, 24.0, &err);
        if (scene == NULL) {
            report("pull", err);
            return 1;
        }
        CHECK(eq(weft_value_type(scene), "scene"));
        size_t elements = weft_value_element_count(scene);
        CHECK(elements == 6 && weft_value_element_name(scene, elements) == NULL);
        const char *names[2] = {"cloth", "hair"};
        for (int e = 0; e < 2; e++) {
            size_t n = 0;
            CHECK(weft_value_element_positions(scene, names[e], NULL, 0, &n, NULL) == WEFT_OK);
            double *p = malloc(n * sizeof *p);
            CHECK(n > 0 && p != NULL);
            if (n > 1) {
                CHECK(weft_value_element_positions(scene, names[e], p, n - 1, &len, &err) == WEFT_BUFFER_TOO_SMALL);
                weft_error_free(err);
                err = NULL;
            }
            CHECK(weft_value_element_positions(scene, names[e], p, n, &len, NULL) == WEFT_OK && len == n);
            for (size_t i = 0; i < n; i++) CHECK(isfinite(p[i]));
            fwrite(p, sizeof *p, n, out);
            free(p);
        }
        uint32_t tri[16 * 2 * 3];
        CHECK(weft_value_element_triangles(scene, "cloth", tri, 96, &len, NULL) == WEFT_OK && len == 96);
        CHECK(weft_value_element_triangles(scene, "hair", NULL, 0, &len, NULL) == WEFT_OK && len == 0);
        uint32_t off[3];
        CHECK(weft_value_element_curve_offsets(scene, "hair", off, 3, &len, NULL) == WEFT_OK && len == 3 && off[2] == 10);
        CHECK(weft_value_element_positions(scene, "nope", NULL, 0, &len, &err) == WEFT_NOT_FOUND);
        weft_error_free(err);
        err = NULL;
        CHECK(weft_value_f64s(scene, NULL, 0, &len, &err) == WEFT_REJECTED);
        weft_error_free(err);
        err = NULL;
        weft_value_free(scene);
    }
    fclose(out);
    WeftValue *center = weft_graph_pull(g, "center", FRAMES, 24.0, NULL);
    double c[3];
    CHECK(weft_value_f64s(center, c, 3, &len, NULL) == WEFT_OK && len == 3);
    printf("cloth centroid at frame %d: %.6f %.6f %.6f\n", FRAMES, c[0], c[1], c[2]);
    weft_value_free(center);

    size_t stats_len = weft_graph_stats_json(g, NULL, 0);
    char *stats = malloc(stats_len + 1);
    CHECK(stats != NULL && weft_graph_stats_json(g, stats, stats_len + 1) == stats_len);
    CHECK(stats != NULL && strstr(stats, "\"solve\"") != NULL);
    free(stats);

    weft_graph_free(g);
    weft_graph_free(NULL);
    weft_value_free(NULL);
    weft_error_free(NULL);
    weft_interrupt_free(NULL);
    if (failures) {
        fprintf(stderr, "%d check(s) failed\n", failures);
        return 1;
    }
    printf("all checks passed\n");
    return 0;
}
