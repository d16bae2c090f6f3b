/* Shader programs (glprog.h). */
#include "glprog.h"

#include <GLES3/gl3.h>

static mts_result compile(const char *what, GLenum type, const char *const *parts, int n,
                          GLuint *out, mts_error *err)
{
    const char *stage = type == GL_VERTEX_SHADER ? "vertex" : "fragment";
    GLuint s = glCreateShader(type);
    if (!s)
        return mts_error_set(err, MTS_ERR_INTERNAL, "%s: glCreateShader(%s) returned 0 (0x%04x)",
                             what, stage, (unsigned)glGetError());
    glShaderSource(s, n, parts, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[400] = {0};
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        glDeleteShader(s);
        return mts_error_set(err, MTS_ERR_INTERNAL, "%s: %s shader does not compile: %s", what,
                             stage, log);
    }
    *out = s;
    return MTS_OK;
}

mts_result mts_glprog_build(const char *what, const char *const *vertex, int vertex_parts,
                            const char *const *fragment, int fragment_parts, unsigned int *program,
                            mts_error *err)
{
    *program = 0;
    GLuint vs = 0, fs = 0;
    mts_result rc = compile(what, GL_VERTEX_SHADER, vertex, vertex_parts, &vs, err);
    if (rc != MTS_OK)
        return rc;
    rc = compile(what, GL_FRAGMENT_SHADER, fragment, fragment_parts, &fs, err);
    if (rc != MTS_OK) {
        glDeleteShader(vs);
        return rc;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, vs);
    glAttachShader(p, fs);
    glLinkProgram(p);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[400] = {0};
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        glDeleteProgram(p);
        return mts_error_set(err, MTS_ERR_INTERNAL, "%s: program does not link: %s", what, log);
    }
    *program = p;
    return MTS_OK;
}
