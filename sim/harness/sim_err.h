/*
 * sim_err.h - the harness's one way to report an error: a printf-style message into a
 * caller's buffer (what, where, what was expected), which the CLI prints as one line.
 */
#ifndef SIM_ERR_H
#define SIM_ERR_H

#include <stddef.h>

/** Format the message into err[errlen] (truncated, always terminated); no-op when err is NULL. */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
void sim_set_err(char *err, size_t errlen, const char *fmt, ...);

#endif
