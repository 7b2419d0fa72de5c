/* cli.h - helpers shared by the haarlight subcommands. */
#ifndef HL_CLI_H
#define HL_CLI_H

#include <stdint.h>

#include "haarlight.h"

/* Prints "haarlight: <fmt with arg>" and the usage; returns 2. */
int usage_error(const char *usage, const char *fmt, const char *arg);
/* Strict parsers: the whole string must be a number in range. */
int parse_u32(const char *s, uint32_t *out);
int parse_float(const char *s, float *out);
int parse_device(const char *s, hl_context_desc *cd);
/* "x,y,z" of finite numbers. */
int parse_vec3(const char *s, float v[3]);
/* An OpenCL context from cl_desc and a reference context beside it (for
 * comparing the two); prints the error and returns 0 on failure. */
int cli_context_pair(const hl_context_desc *cl_desc, hl_context **cl, hl_context **ref);
/* Prints the context's last error; returns the exit code for r. */
int cli_fail(hl_context *ctx, hl_result r);

int cmd_relight(int argc, char **argv);
int cmd_check(int argc, char **argv);
int cmd_bench(int argc, char **argv);

#endif
