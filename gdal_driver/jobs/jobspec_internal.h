/*
 * jobspec_internal.h - what values.c shares with build.c: the rules and
 * value checks the builders run, and the strings a job points into.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_JOBSPEC_INTERNAL_H
#define TS_JOBSPEC_INTERNAL_H

#include <stddef.h>

#include "jobspec.h"

/* A copy of s owned by v (the job points into it). */
const char *tsjob__keep(tsjob_values *v, const char *s);

/* snprintf into the message buffer. */
void tsjob__msgf(char *msg, size_t len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Is `name` given?  "@stage": the first parameter of that stage given, or
 * NULL; otherwise the name itself, or NULL. */
const char *tsjob__given(const tsjob_values *v, const char *name);

/* The job's rules that apply to this front end (cli: the command line's
 * output rules too); 0, or -1 with the rule's message. */
int tsjob__check_rules(const tsjob_values *v, int cli, char *msg, size_t len);

/* A whole string as a finite number; "AxB" or "A,B" as two. 0 or -1. */
int tsjob__parse_number(const char *s, double *out);
int tsjob__parse_pair(const char *s, char sep, double *a, double *b);

/* Every value against its option's kind and range. 0 or -1 with a message. */
int tsjob__check_values(tsjob_values *v, char *msg, size_t len);

/* The values of a stage's parameters into its core parameter struct. */
int tsjob__apply_params(const tsjob_values *v, const char *stage, void *params, char *msg,
                        size_t len);

/* A choice option given ("--ridges") as the parameter it sets. */
void tsjob__expand_choices(tsjob_values *v);

#endif
