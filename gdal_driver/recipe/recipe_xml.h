/*
 * recipe_xml.h - a job's values in a recipe's XML (recipe_xml.c), by the
 * recipe form each option declares (jobspec.h: "Element", "Element@attr").
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_RECIPE_XML_H
#define TS_RECIPE_XML_H

#include <cpl_minixml.h>

#include "jobspec.h"

/* Read the job's element into v: `resolve` turns a file name of the recipe
 * into the one to open (relative to the recipe) and may refuse it
 * (returning NULL with msg set).  0, or -1 with msg. */
int tsrecipe_values_from_xml(tsjob_values *v, const CPLXMLNode *node,
                             const char *(*resolve)(void *user, const char *name, char *msg,
                                                    size_t len),
                             void *user, char *msg, size_t len);

/* Write v as the job's element under root; `rel` turns a file name into its
 * form in the recipe (relative to it). */
/* Refuse what the declarations do not give a recipe: an attribute of <TerraSynth> other
 * than version, a second element beside the job's, an element or attribute the job's
 * options do not name (a typo is refused, not ignored); 0, or -1 with msg. */
int tsrecipe_check_schema(const tsjob_decl *job, const CPLXMLNode *top, const CPLXMLNode *node,
                          char *msg, size_t len);

void tsrecipe_values_to_xml(const tsjob_values *v, CPLXMLNode *root,
                            const char *(*rel)(void *user, const char *name), void *user);

#endif
