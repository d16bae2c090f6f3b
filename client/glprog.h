/* A GLES shader program from sources, for the renderer and the HUD: each
 * stage compiled from its parts (glShaderSource's strings, e.g. a #version
 * line, #defines, the body), linked, the compiler's or linker's log in the
 * error. The caller's context must be current. GLuint is unsigned int in
 * every GLES header; this one includes none, so a GLES 3.0 and a 3.2 caller
 * can both use it. */
#ifndef MTS_GLPROG_H
#define MTS_GLPROG_H

#include "error.h"

/* what names the program in messages ("render", "HUD"). On failure nothing
 * is left behind and *program is 0. */
mts_result mts_glprog_build(const char *what, const char *const *vertex, int vertex_parts,
                            const char *const *fragment, int fragment_parts, unsigned int *program,
                            mts_error *err);

#endif
