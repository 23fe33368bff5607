/*
 * expr.c — the expression language of DESIGN.md section 3: a parser that emits
 * stack-machine bytecode with constant folding and fused opcodes, and three
 * evaluators (value; value + gradient; value + gradient + Hessian) that carry exact
 * derivatives by forward-mode automatic differentiation to second order.
 *
 * Grammar (whitespace anywhere between tokens; names are case-sensitive):
 *
 *   program   := { NAME '=' sum ';' } sum [ ';' ]
 *   sum       := product { ('+' | '-') product }
 *   product   := signed { ('*' | '/') signed }
 *   signed    := { '+' | '-' } power              -x^2 = -(x^2)
 *   power     := primary [ '^' signed ]           right associative: 2^3^2 = 2^9
 *   primary   := NUMBER | 'x' | 'y' | 'z' | 'pi' | PARAMETER
 *              | FUNCTION '(' sum { ',' sum } ')' | '(' sum ')'
 *   NUMBER    := ( DIGITS [ '.' [DIGITS] ] | '.' DIGITS ) [ ('e'|'E') ['+'|'-'] DIGITS ]
 *   NAME      := [A-Za-z_][A-Za-z0-9_]*
 *
 * Functions: sqrt exp log sin cos tan tanh abs (one argument), pow atan2 (two), min max
 * (two or more). Parameters are constants evaluated at compile time: they may use
 * numbers, pi, functions and earlier parameters, never x, y, z; a parameter cannot be
 * redefined and cannot take a reserved name (x y z pi or a function name).
 *
 * Semantics at singular points (evaluation never traps):
 *  - a / 0 is NaN (not +-inf: the sign of a pole is meaningless to the surface
 *    oracle, which treats NaN as an error); likewise 0^c for c < 0 and x^-n at x = 0;
 *  - log of a negative number, sqrt of a negative number, a negative base with a
 *    non-integer exponent: NaN; log(0) = -inf (IEEE);
 *  - x^0 = 1 for every x (as C's pow), x^1 = x;
 *  - derivatives at non-differentiable points: abs(u) at u = 0 takes the branch u
 *    (gradient +grad u); min(a, b) and max(a, b) at a == b take the first argument;
 *    sqrt at 0 gives infinite (or NaN) derivatives; the derivative of a^b with respect
 *    to a variable exponent b is NaN for a < 0 (a^b is undefined for nearby
 *    non-integer b; forward mode then carries NaN into every gradient component, as
 *    0 * NaN is NaN) and 0 for a == 0 < b. A constant exponent (a number, a parameter
 *    or any constant expression) has no such issue: x^3 at x < 0 is exact.
 *
 * Compilation (no recursion anywhere: inputs like 10^6 nested parentheses or 10^6-term
 * sums compile in linear time and bounded C stack):
 *  1. a shunting-yard parser with explicit, heap-allocated operator and operand stacks
 *     builds an expression tree in one node array, folding constants as nodes are
 *     made (parameters are folded values; a constant exponent becomes a unary power);
 *  2. each node records the stack slots its code needs (Sethi-Ullman: the deeper
 *     operand of + - * / is evaluated first, swapped - and / use RSUB / RDIV), checked
 *     against AS_EXPR_MAX_STACK as the node is made, with the operator's column;
 *  3. a post-order walk with an explicit stack emits the bytecode.
 *
 * Bytecode: a stack machine with the top of the stack cached in a register (value
 * mode). Instructions carry their operands, so that the shapes of implicit surfaces
 * take one instruction each: constants (ADDC, MULC, RSUBC, RDIVC...), "terms" d*v,
 * d*(v + c), d*(v + c)^2 recognised in the source (x, 3*x, -x, x - 1, (z + k)^2,
 * 2*x^2, -(y - 1)^2...; PUSH_*, ADD_*, RSUB_*, MUL_*), (t + c)^2 (ADDSQ). Every such
 * rewriting is exact in IEEE arithmetic (t - c == t + (-c), -L == (-1)*L, L*k == k*L,
 * (c - v)^2 == (v - c)^2, 1*L == L), so the three evaluators return bitwise the value
 * of the formula evaluated as written. The torus compiles to 6 instructions, the
 * chair to 11. The evaluators are three switch loops (value; value + gradient; value +
 * gradient + Hessian) over the same code; a stack slot carries f, or f and its
 * gradient, or f, gradient and Hessian (forward-mode automatic differentiation); term
 * instructions touch only their variable's gradient and Hessian entries.
 */
#include "surface/expr.h"

#include <locale.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define AS_EXPR_PI 3.14159265358979323846264338327950288
/* Longest accepted numeric literal (characters). */
#define AS_EXPR_MAX_NUMBER 400
/* Integer exponents up to this magnitude use repeated squaring (powi); larger ones pow. */
#define AS_EXPR_MAX_POWI 1048576
/* Longest accepted source (bytes): keeps node indices within int32. */
#define AS_EXPR_MAX_LENGTH (1 << 28)

/* ---- bytecode ----------------------------------------------------------------------- */

/* t is the top of the stack, s the element below it, c and d the instruction's constants.
 * A "term" is d*v, d*(v + c) or d*(v + c)^2 with v = p[n]: the compiler recognises these
 * shapes in the source (x, -x, 3*x, x - 1, (z + k)^2, 2*x^2, -(y - 1)^2 ...) and they
 * are exact rewritings of it (d*L is L*k or -L as written; 1*L == L), so that values
 * are bitwise those of the formula evaluated as written. */
enum {
    OP_PUSHC,  /* push c */
    OP_NEG,    /* t = -t */
    OP_SQ,     /* t = t*t */
    OP_ADDSQ,  /* t = (t + c)*(t + c) */
    OP_POWI,   /* t = t^n, integer n != 0, 1, 2 (repeated squaring) */
    OP_POWC,   /* t = t^c, c not an integer (pow) */
    OP_SQRT,   /* t = f(t) ... */
    OP_EXP,
    OP_LOG,
    OP_SIN,
    OP_COS,
    OP_TAN,
    OP_TANH,
    OP_ABS,
    OP_ADD,    /* t = s + t (pops one) */
    OP_SUB,    /* t = s - t */
    OP_RSUB,   /* t = t - s */
    OP_MUL,    /* t = s * t */
    OP_DIV,    /* t = s / t */
    OP_RDIV,   /* t = t / s */
    OP_POW,    /* t = s ^ t */
    OP_ATAN2,  /* t = atan2(s, t) */
    OP_MIN,    /* t = min(s, t), s on ties */
    OP_MAX,    /* t = max(s, t), s on ties */
    OP_ADDC,   /* t = t + c (also t - c as t + (-c), identical in IEEE) */
    OP_MULC,   /* t = t * c */
    OP_DIVC,   /* t = t / c */
    OP_RSUBC,  /* t = c - t */
    OP_RDIVC,  /* t = c / t */
    /* terms T: V = d*v, L = d*(v + c), S = d*(v + c)^2 */
    OP_PUSH_V, /* push T */
    OP_PUSH_L,
    OP_PUSH_S,
    OP_ADD_V,  /* t = t + T (t - T is t + T with d negated) */
    OP_ADD_L,
    OP_ADD_S,
    OP_RSUB_V, /* t = T - t */
    OP_RSUB_L,
    OP_RSUB_S,
    OP_MUL_V,  /* t = t * T */
    OP_MUL_L,
    OP_MUL_S,
    OP_PUSH_Q, /* push v*v: the term S with c = 0 and d = 1, which (v + 0)^2 * 1 equals */
    OP_ADD_Q,  /* t = t + v*v */
    OP_END,    /* the last instruction: return t */
    OP_COUNT_
};

typedef struct as_insn {
    int32_t op;
    int32_t n; /* variable index 0..2 or integer exponent */
    double c;  /* constant */
    double d;  /* terms: coefficient */
} as_insn;

typedef struct as_param {
    size_t name; /* offset of the NUL-terminated name in names */
    double value;
} as_param;

struct as_expr {
    size_t bytes; /* size of this single block */
    size_t ncode;
    const as_insn *code;
    size_t nparams;
    const as_param *params;
    const char *names;
    int max_stack;
    int uses; /* bit 0: x, bit 1: y, bit 2: z */
};

/* ---- scalar semantics (shared by the evaluators and the constant folder) ------------ */

static inline double v_div(double a, double b) { return b == 0.0 ? NAN : a / b; }

/* u^n for an integer n, |n| <= AS_EXPR_MAX_POWI, by repeated squaring (so negative
 * bases are exact-ish: x^3 == x*(x*x)); u^-n = 1/u^n, and 0^-n is NaN (a pole). */
static inline double v_powi(double u, int n) {
    if (n < 0 && u == 0.0) return NAN;
    double r = 1.0, b = u;
    unsigned k = n < 0 ? (unsigned)(-n) : (unsigned)n;
    while (k) {
        if (k & 1u) r *= b;
        k >>= 1;
        if (k) b *= b;
    }
    return n < 0 ? 1.0 / r : r;
}

static inline double v_pow(double a, double b) {
    if (a == 0.0 && b < 0.0) return NAN;
    return pow(a, b);
}

/* NaN in either argument gives NaN (C's fmin/fmax would drop it). */
static inline double v_min(double a, double b) {
    if (a <= b) return a;
    if (b < a) return b;
    return NAN;
}
static inline double v_max(double a, double b) {
    if (a >= b) return a;
    if (b > a) return b;
    return NAN;
}
/* Which argument min/max take: 0 first, 1 second, -1 unordered (NaN). */
static inline int pick_min(double a, double b) { return a <= b ? 0 : (b < a ? 1 : -1); }
static inline int pick_max(double a, double b) { return a >= b ? 0 : (b > a ? 1 : -1); }

static double v_unary(int op, double u, const as_insn *in) {
    switch (op) {
    case OP_NEG: return -u;
    case OP_SQ: return u * u;
    case OP_POWI: return v_powi(u, in->n);
    case OP_POWC: return v_pow(u, in->c);
    case OP_SQRT: return sqrt(u);
    case OP_EXP: return exp(u);
    case OP_LOG: return log(u);
    case OP_SIN: return sin(u);
    case OP_COS: return cos(u);
    case OP_TAN: return tan(u);
    case OP_TANH: return tanh(u);
    case OP_ABS: return fabs(u);
    default: return NAN;
    }
}

/* ---- compiler: lexer ---------------------------------------------------------------- */

enum {
    T_END,
    T_NUM,
    T_NAME,
    T_PLUS,
    T_MINUS,
    T_STAR,
    T_SLASH,
    T_CARET,
    T_LPAREN,
    T_RPAREN,
    T_COMMA,
    T_SEMI,
    T_EQ
};

typedef struct tok {
    int kind;
    size_t pos; /* 0-based byte offset; the column is pos + 1 */
    size_t len;
    double num;
} tok;

/* A pending operator or bracket of the shunting-yard parser. */
enum { K_ADD, K_SUB, K_MUL, K_DIV, K_POW, K_NEG, K_PAREN, K_FUNC };

typedef struct opent {
    int kind;
    int func;     /* K_FUNC: index in FUNCS */
    size_t pos;   /* the token's offset (K_FUNC: the function's name) */
    size_t ppos;  /* K_PAREN, K_FUNC: the offset of the '(' */
    size_t nargs; /* K_FUNC: completed arguments so far */
} opent;

/* The expression tree: nodes live in one array and refer to their operands by index.
 * Folding happens as nodes are made, so a node of kind N_CONST is a folded value. */
enum { N_CONST, N_VAR, N_UN, N_BIN };

typedef struct node {
    int32_t kind;
    int32_t op;   /* N_UN: opcode (OP_NEG, OP_SQ, OP_POWI...); N_BIN: B_* */
    int32_t a, b; /* operands */
    int32_t n;    /* N_VAR: variable index; OP_POWI: exponent */
    int32_t need; /* evaluation stack slots its code needs */
    double c;     /* N_CONST: value; OP_POWC: exponent */
} node;

typedef struct pparam {
    size_t pos, len; /* the name in the source */
    double value;
} pparam;

typedef struct parser {
    anistar_context *ctx;
    const char *src;
    size_t srclen;
    tok cur;
    tok prev;      /* the previously consumed token (kind T_END at a statement start) */
    int in_param;  /* parsing a parameter definition */
    size_t pname, pnamelen; /* the parameter being defined */
    node *nodes;
    size_t nnodes, capnodes;
    int32_t *vs; /* the operand stack of the shunting-yard parser: node indices */
    size_t nvs, capvs;
    as_insn *code;
    size_t ncode, capcode;
    opent *ops;
    size_t nops, capops;
    pparam *params;
    size_t nparams, capparams;
} parser;

typedef struct func_def {
    const char *name;
    int arity; /* -2: two or more */
    int op;    /* an opcode (one argument) or a B_* code (two or more) */
} func_def;

enum { B_ADD, B_SUB, B_MUL, B_DIV, B_POW, B_ATAN2, B_MIN, B_MAX };

static const func_def FUNCS[] = {
    {"sqrt", 1, OP_SQRT}, {"exp", 1, OP_EXP},   {"log", 1, OP_LOG},   {"sin", 1, OP_SIN},
    {"cos", 1, OP_COS},   {"tan", 1, OP_TAN},   {"tanh", 1, OP_TANH}, {"abs", 1, OP_ABS},
    {"min", -2, B_MIN},   {"max", -2, B_MAX},   {"pow", 2, B_POW},    {"atan2", 2, B_ATAN2},
};
#define AS_EXPR_NFUNCS ((int)(sizeof FUNCS / sizeof FUNCS[0]))
#define AS_EXPR_KNOWN_FUNCS "sqrt exp log sin cos tan tanh abs min max pow atan2"

static inline int is_digit(int c) { return c >= '0' && c <= '9'; }
static inline int is_name0(int c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}
static inline int is_name1(int c) { return is_name0(c) || is_digit(c); }
static inline int is_space(int c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}

/* A shown excerpt of a token is at most this long. */
#define AS_EXPR_SHOW 40
static int show_len(size_t len) { return (int)(len > AS_EXPR_SHOW ? AS_EXPR_SHOW : len); }

static anistar_status syntax(parser *ps, size_t pos, const char *what) {
    return as_fail(ps->ctx, ANISTAR_EFORMAT, "expression, column %zu: %s", pos + 1, what);
}

/* Convert a validated decimal literal (C locale syntax) to a double. */
static int convert_number(const char *s, size_t len, double *out) {
    char buf[AS_EXPR_MAX_NUMBER + 1];
    memcpy(buf, s, len);
    buf[len] = '\0';
    char *end;
    double v = strtod(buf, &end);
    if ((size_t)(end - buf) != len) {
        /* A locale whose decimal point is not '.': retry with its own. */
        const struct lconv *lc = localeconv();
        char dp = (lc && lc->decimal_point && lc->decimal_point[0]) ? lc->decimal_point[0] : '.';
        for (size_t i = 0; i < len; i++)
            if (buf[i] == '.') buf[i] = dp;
        v = strtod(buf, &end);
        if ((size_t)(end - buf) != len) return -1;
    }
    *out = v;
    return 0;
}

/* Lex the token starting at or after pos into *t. Fails (EFORMAT) on a malformed
 * number or an unexpected character. */
static anistar_status lex_at(parser *ps, size_t pos, tok *t) {
    const char *s = ps->src;
    size_t n = ps->srclen;
    while (pos < n && is_space((unsigned char)s[pos])) pos++;
    t->pos = pos;
    t->len = 1;
    t->num = 0.0;
    if (pos >= n) {
        t->kind = T_END;
        t->len = 0;
        return ANISTAR_OK;
    }
    int c = (unsigned char)s[pos];
    if (is_digit(c) || (c == '.' && pos + 1 < n && is_digit((unsigned char)s[pos + 1]))) {
        size_t i = pos;
        int ok = 1;
        while (i < n && is_digit((unsigned char)s[i])) i++;
        if (i < n && s[i] == '.') {
            i++;
            while (i < n && is_digit((unsigned char)s[i])) i++;
        }
        if (i < n && (s[i] == 'e' || s[i] == 'E')) {
            size_t j = i + 1;
            if (j < n && (s[j] == '+' || s[j] == '-')) j++;
            if (j < n && is_digit((unsigned char)s[j])) {
                while (j < n && is_digit((unsigned char)s[j])) j++;
                i = j;
            } else {
                ok = 0; /* an exponent without digits */
            }
        }
        if (i < n && (is_name1((unsigned char)s[i]) || s[i] == '.')) ok = 0;
        if (!ok) {
            /* Show the whole run of number-like characters. */
            size_t j = pos;
            while (j < n && (is_name1((unsigned char)s[j]) || s[j] == '.' ||
                             ((s[j] == '+' || s[j] == '-') && j > pos &&
                              (s[j - 1] == 'e' || s[j - 1] == 'E'))))
                j++;
            return as_fail(ps->ctx, ANISTAR_EFORMAT, "expression, column %zu: malformed number '%.*s'",
                           pos + 1, show_len(j - pos), s + pos);
        }
        t->kind = T_NUM;
        t->len = i - pos;
        if (t->len > AS_EXPR_MAX_NUMBER)
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: number longer than %d characters", pos + 1,
                           AS_EXPR_MAX_NUMBER);
        if (convert_number(s + pos, t->len, &t->num) || !isfinite(t->num))
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: number '%.*s' is out of range", pos + 1,
                           show_len(t->len), s + pos);
        return ANISTAR_OK;
    }
    if (is_name0(c)) {
        size_t i = pos + 1;
        while (i < n && is_name1((unsigned char)s[i])) i++;
        t->kind = T_NAME;
        t->len = i - pos;
        return ANISTAR_OK;
    }
    switch (c) {
    case '+': t->kind = T_PLUS; return ANISTAR_OK;
    case '-': t->kind = T_MINUS; return ANISTAR_OK;
    case '*': t->kind = T_STAR; return ANISTAR_OK;
    case '/': t->kind = T_SLASH; return ANISTAR_OK;
    case '^': t->kind = T_CARET; return ANISTAR_OK;
    case '(': t->kind = T_LPAREN; return ANISTAR_OK;
    case ')': t->kind = T_RPAREN; return ANISTAR_OK;
    case ',': t->kind = T_COMMA; return ANISTAR_OK;
    case ';': t->kind = T_SEMI; return ANISTAR_OK;
    case '=': t->kind = T_EQ; return ANISTAR_OK;
    default: break;
    }
    if (c >= 0x21 && c < 0x7f)
        return as_fail(ps->ctx, ANISTAR_EFORMAT, "expression, column %zu: unexpected character '%c'",
                       pos + 1, c);
    return as_fail(ps->ctx, ANISTAR_EFORMAT,
                   "expression, column %zu: unexpected character (byte 0x%02x)", pos + 1, c);
}

static anistar_status advance(parser *ps) {
    ps->prev = ps->cur;
    return lex_at(ps, ps->cur.pos + ps->cur.len, &ps->cur);
}

static int tok_is(const parser *ps, const tok *t, const char *word) {
    size_t l = strlen(word);
    return t->kind == T_NAME && t->len == l && memcmp(ps->src + t->pos, word, l) == 0;
}

static int find_func(const parser *ps, const tok *t) {
    for (int i = 0; i < AS_EXPR_NFUNCS; i++)
        if (tok_is(ps, t, FUNCS[i].name)) return i;
    return -1;
}

static int is_reserved(const parser *ps, const tok *t) {
    return tok_is(ps, t, "x") || tok_is(ps, t, "y") || tok_is(ps, t, "z") ||
           tok_is(ps, t, "pi") || find_func(ps, t) >= 0;
}

static long find_param(const parser *ps, const tok *t) {
    for (size_t i = 0; i < ps->nparams; i++)
        if (ps->params[i].len == t->len &&
            memcmp(ps->src + ps->params[i].pos, ps->src + t->pos, t->len) == 0)
            return (long)i;
    return -1;
}

/* A short description of a token for messages: "'+'", "'foo'", "the end". */
static void describe(const parser *ps, const tok *t, char *buf, size_t size) {
    if (t->kind == T_END)
        snprintf(buf, size, "the end of the expression");
    else
        snprintf(buf, size, "'%.*s'", show_len(t->len), ps->src + t->pos);
}

/* ---- compiler: expression tree with folding ----------------------------------------- */

static anistar_status nomem(parser *ps) {
    return as_fail(ps->ctx, ANISTAR_ENOMEM, "expression: out of memory while compiling");
}

/* Node indices are int32: the source length is limited so that they cannot overflow. */
static anistar_status new_node(parser *ps, int kind, int op, int32_t a, int32_t b, int n, double c,
                               int32_t *out) {
    if (as_grow(ps->ctx, (void **)&ps->nodes, &ps->capnodes, ps->nnodes + 1, sizeof *ps->nodes))
        return nomem(ps);
    node *nd = &ps->nodes[ps->nnodes];
    nd->kind = kind;
    nd->op = op;
    nd->a = a;
    nd->b = b;
    nd->n = n;
    nd->c = c;
    nd->need = 1;
    *out = (int32_t)ps->nnodes++;
    return ANISTAR_OK;
}

/* A term d*v (T_V), d*(v + c) (T_L) or d*(v + c)^2 (T_S) of variable n. */
enum { T_NONE = -1, T_V = 0, T_L = 1, T_S = 2 };

typedef struct term {
    int kind, n;
    double c, d;
} term;

/* The constant operand of a binary node, or NULL; *other gets the other operand. */
static const node *const_operand(const parser *ps, const node *nd, int32_t *other) {
    if (ps->nodes[nd->b].kind == N_CONST) {
        *other = nd->a;
        return &ps->nodes[nd->b];
    }
    if (ps->nodes[nd->a].kind == N_CONST) {
        *other = nd->b;
        return &ps->nodes[nd->a];
    }
    return NULL;
}

/* v + c for x + c, c + x, x - c (x - c == x + (-c) exactly): returns the variable
 * index and sets *c, or -1. */
static int shifted_var(const parser *ps, int32_t i, double *c) {
    const node *nd = &ps->nodes[i];
    if (nd->kind != N_BIN || (nd->op != B_ADD && nd->op != B_SUB)) return -1;
    const node *a = &ps->nodes[nd->a], *b = &ps->nodes[nd->b];
    if (a->kind == N_VAR && b->kind == N_CONST) {
        *c = nd->op == B_ADD ? b->c : -b->c;
        return a->n;
    }
    if (nd->op == B_ADD && a->kind == N_CONST && b->kind == N_VAR) {
        *c = a->c;
        return b->n;
    }
    return -1;
}

/* Is node i a term? Recognised shapes (each an exact rewriting):
 *   [k * | * k | -] ( v | v + c | c + v | v - c | v^2 | (v + c)^2 | (c - v)^2 ... )
 * where (c - v)^2 == (v - c)^2 exactly, -L == (-1)*L, L*k == k*L, and (-L)*k == (-k)*L. */
static term term_of(const parser *ps, int32_t i) {
    term t = {T_NONE, 0, 0.0, 1.0};
    const node *nd = &ps->nodes[i];
    int32_t x;
    if (nd->kind == N_BIN && nd->op == B_MUL) {
        const node *k = const_operand(ps, nd, &x);
        if (!k) return t;
        t.d = k->c;
        nd = &ps->nodes[x];
    }
    if (nd->kind == N_UN && nd->op == OP_NEG) {
        t.d = -t.d;
        nd = &ps->nodes[nd->a];
    }
    if (nd->kind == N_VAR) {
        t.kind = T_V;
        t.n = nd->n;
        return t;
    }
    int32_t self = (int32_t)(nd - ps->nodes);
    int n = shifted_var(ps, self, &t.c);
    if (n >= 0) {
        t.kind = T_L;
        t.n = n;
        return t;
    }
    if (nd->kind == N_UN && nd->op == OP_SQ) {
        const node *a = &ps->nodes[nd->a];
        if (a->kind == N_VAR) {
            t.kind = T_S;
            t.n = a->n;
            t.c = 0.0; /* (v + 0)^2 == v^2 exactly, zeros included */
            return t;
        }
        n = shifted_var(ps, nd->a, &t.c);
        if (n < 0 && a->kind == N_BIN && a->op == B_SUB && ps->nodes[a->a].kind == N_CONST &&
            ps->nodes[a->b].kind == N_VAR) { /* (c - v)^2 == (v + (-c))^2 exactly */
            n = ps->nodes[a->b].n;
            t.c = -ps->nodes[a->a].c;
        }
        if (n >= 0) {
            t.kind = T_S;
            t.n = n;
            return t;
        }
    }
    t.kind = T_NONE;
    return t;
}

/* How a binary node becomes code: evaluate `first` then (if >= 0) `second`, then the
 * instruction `in`. need is the number of stack slots that takes.
 * design (Sethi-Ullman with fused operands):
 *   - a constant operand of + - * / is folded into the instruction (ADDC, RSUBC...),
 *     a term operand of + - * likewise (ADD_S, RSUB_V, MUL_L...): no slot;
 *   - otherwise + - * / evaluate the operand needing more slots first (swapped - and /
 *     become RSUB / RDIV); pow, atan2, min, max keep their order, so that ties of min /
 *     max and the derivative formulas never depend on the operands' shapes. */
typedef struct plan {
    int32_t first, second;
    as_insn in;
    int need;
} plan;

static plan make_plan(const parser *ps, const node *nd) {
    plan p;
    int32_t a = nd->a, b = nd->b;
    int bop = nd->op;
    int arith = bop == B_ADD || bop == B_SUB || bop == B_MUL || bop == B_DIV;
    int na = ps->nodes[a].need, nb = ps->nodes[b].need;
    p.in.n = 0;
    p.in.c = 0.0;
    p.in.d = 0.0;
    p.second = -1;
    if (arith && ps->nodes[b].kind == N_CONST) {
        double c = ps->nodes[b].c;
        p.first = a;
        p.need = na;
        p.in.c = c;
        p.in.op = bop == B_ADD ? OP_ADDC : bop == B_SUB ? OP_ADDC : bop == B_MUL ? OP_MULC : OP_DIVC;
        if (bop == B_SUB) p.in.c = -c; /* t - c == t + (-c) exactly */
        return p;
    }
    if (arith && ps->nodes[a].kind == N_CONST) {
        p.first = b;
        p.need = nb;
        p.in.c = ps->nodes[a].c;
        p.in.op = bop == B_ADD ? OP_ADDC : bop == B_SUB ? OP_RSUBC : bop == B_MUL ? OP_MULC : OP_RDIVC;
        return p;
    }
    if (arith && bop != B_DIV) {
        term tb = term_of(ps, b);
        if (tb.kind != T_NONE) { /* t + T, t - T == t + (-d)L exactly, t * T */
            p.first = a;
            p.need = na;
            p.in.n = tb.n;
            p.in.c = tb.c;
            p.in.d = bop == B_SUB ? -tb.d : tb.d;
            p.in.op = (bop == B_MUL ? OP_MUL_V : OP_ADD_V) + tb.kind;
            if (p.in.op == OP_ADD_S && p.in.c == 0.0 && p.in.d == 1.0) p.in.op = OP_ADD_Q;
            return p;
        }
        term ta = term_of(ps, a);
        if (ta.kind != T_NONE) { /* T + t, T - t, T * t */
            p.first = b;
            p.need = nb;
            p.in.n = ta.n;
            p.in.c = ta.c;
            p.in.d = ta.d;
            p.in.op = (bop == B_MUL ? OP_MUL_V : bop == B_SUB ? OP_RSUB_V : OP_ADD_V) + ta.kind;
            if (p.in.op == OP_ADD_S && p.in.c == 0.0 && p.in.d == 1.0) p.in.op = OP_ADD_Q;
            return p;
        }
    }
    if (arith && nb > na) {
        p.first = b;
        p.second = a;
        p.need = nb > 1 + na ? nb : 1 + na;
        p.in.op = bop == B_ADD ? OP_ADD : bop == B_SUB ? OP_RSUB : bop == B_MUL ? OP_MUL : OP_RDIV;
        return p;
    }
    p.first = a;
    p.second = b;
    p.need = na > 1 + nb ? na : 1 + nb;
    switch (bop) {
    case B_ADD: p.in.op = OP_ADD; break;
    case B_SUB: p.in.op = OP_SUB; break;
    case B_MUL: p.in.op = OP_MUL; break;
    case B_DIV: p.in.op = OP_DIV; break;
    case B_POW: p.in.op = OP_POW; break;
    case B_ATAN2: p.in.op = OP_ATAN2; break;
    case B_MIN: p.in.op = OP_MIN; break;
    default: p.in.op = OP_MAX; break;
    }
    return p;
}

static anistar_status push_value(parser *ps, int32_t i) {
    if (as_grow(ps->ctx, (void **)&ps->vs, &ps->capvs, ps->nvs + 1, sizeof *ps->vs))
        return nomem(ps);
    ps->vs[ps->nvs++] = i;
    return ANISTAR_OK;
}

static anistar_status push_const(parser *ps, double v) {
    int32_t i = -1;
    anistar_status st = new_node(ps, N_CONST, 0, -1, -1, 0, v, &i);
    if (st) return st;
    return push_value(ps, i);
}

static anistar_status push_var(parser *ps, int n) {
    int32_t i = -1;
    anistar_status st = new_node(ps, N_VAR, 0, -1, -1, n, 0.0, &i);
    if (st) return st;
    return push_value(ps, i);
}

/* A unary node op(a) (with the exponent n or c of POWI / POWC), folded where exact. */
static anistar_status make_unary(parser *ps, int op, int32_t a, int n, double c, int32_t *out) {
    node *na = &ps->nodes[a];
    if (na->kind == N_CONST) {
        as_insn in = {op, n, c, 0.0};
        return new_node(ps, N_CONST, 0, -1, -1, 0, v_unary(op, na->c, &in), out);
    }
    if (op == OP_NEG && na->kind == N_UN && na->op == OP_NEG) { /* -(-t) == t */
        *out = na->a;
        return ANISTAR_OK;
    }
    if (op == OP_NEG && na->kind == N_BIN && na->op == B_MUL &&
        (ps->nodes[na->b].kind == N_CONST || ps->nodes[na->a].kind == N_CONST)) {
        /* -(t*c) == t*(-c) exactly: keeps the product one MULC */
        int cb = ps->nodes[na->b].kind == N_CONST;
        int32_t t = cb ? na->a : na->b;
        double cv = ps->nodes[cb ? na->b : na->a].c;
        int32_t k = -1;
        anistar_status st = new_node(ps, N_CONST, 0, -1, -1, 0, -cv, &k);
        if (st) return st;
        st = new_node(ps, N_BIN, B_MUL, t, k, 0, 0.0, out);
        if (st) return st;
        ps->nodes[*out].need = make_plan(ps, &ps->nodes[*out]).need;
        return ANISTAR_OK;
    }
    anistar_status st = new_node(ps, N_UN, op, a, -1, n, c, out);
    if (st) return st;
    ps->nodes[*out].need = ps->nodes[a].need;
    return ANISTAR_OK;
}

static anistar_status apply_unary(parser *ps, int op, int n, double c) {
    int32_t r = -1;
    anistar_status st = make_unary(ps, op, ps->vs[ps->nvs - 1], n, c, &r);
    if (st) return st;
    ps->vs[ps->nvs - 1] = r;
    return ANISTAR_OK;
}

static anistar_status check_need(parser *ps, int need, size_t pos) {
    if (need > AS_EXPR_MAX_STACK)
        return as_fail(ps->ctx, ANISTAR_EFORMAT,
                       "expression, column %zu: nested too deeply: evaluation would need more "
                       "than %d stack slots",
                       pos + 1, AS_EXPR_MAX_STACK);
    return ANISTAR_OK;
}

static double fold_binary(int b, double l, double r) {
    switch (b) {
    case B_ADD: return l + r;
    case B_SUB: return l - r;
    case B_MUL: return l * r;
    case B_DIV: return v_div(l, r);
    case B_POW:
        if (r == floor(r) && fabs(r) <= AS_EXPR_MAX_POWI) return r == 0.0 ? 1.0 : v_powi(l, (int)r);
        return v_pow(l, r);
    case B_ATAN2: return atan2(l, r);
    case B_MIN: return v_min(l, r);
    case B_MAX: return v_max(l, r);
    default: return NAN;
    }
}

/* Combine the two top operands with binary operation b (B_*); pos is the operator's
 * offset for messages. Two constants fold; a constant exponent becomes a unary power
 * (x^1 = x, x^0 = 1, x^2 = SQ, integers POWI, others POWC). */
static anistar_status apply_binary(parser *ps, int b, size_t pos) {
    int32_t ib = ps->vs[--ps->nvs];
    int32_t ia = ps->vs[ps->nvs - 1];
    int32_t r = -1;
    anistar_status st;
    const node *na = &ps->nodes[ia], *nb = &ps->nodes[ib];
    if (na->kind == N_CONST && nb->kind == N_CONST) {
        st = new_node(ps, N_CONST, 0, -1, -1, 0, fold_binary(b, na->c, nb->c), &r);
    } else if (b == B_POW && nb->kind == N_CONST) {
        double c = nb->c;
        if (c == 1.0) /* pow(t, 1) == t */
            r = ia, st = ANISTAR_OK;
        else if (c == 0.0) /* pow(t, 0) == 1 for every t */
            st = new_node(ps, N_CONST, 0, -1, -1, 0, 1.0, &r);
        else if (c == 2.0)
            st = make_unary(ps, OP_SQ, ia, 0, 0.0, &r);
        else if (c == floor(c) && fabs(c) <= AS_EXPR_MAX_POWI)
            st = make_unary(ps, OP_POWI, ia, (int)c, 0.0, &r);
        else
            st = make_unary(ps, OP_POWC, ia, 0, c, &r);
    } else {
        st = new_node(ps, N_BIN, b, ia, ib, 0, 0.0, &r);
        if (!st) {
            ps->nodes[r].need = make_plan(ps, &ps->nodes[r]).need;
            st = check_need(ps, ps->nodes[r].need, pos);
        }
    }
    if (st) return st;
    ps->vs[ps->nvs - 1] = r;
    return ANISTAR_OK;
}

/* ---- compiler: code generation ------------------------------------------------------- */

static anistar_status emit(parser *ps, as_insn in) {
    if (as_grow(ps->ctx, (void **)&ps->code, &ps->capcode, ps->ncode + 1, sizeof *ps->code))
        return nomem(ps);
    ps->code[ps->ncode++] = in;
    return ANISTAR_OK;
}

/* Emit the code of the tree rooted at root: a post-order walk with an explicit stack
 * (trees of long sums are as deep as they are long). */
static anistar_status gen_code(parser *ps, int32_t root) {
    typedef struct frame {
        int32_t node;
        int32_t state; /* children already emitted */
    } frame;
    frame *fs = NULL;
    size_t nf = 0, capf = 0;
    anistar_status st = ANISTAR_OK;
    if (as_grow(ps->ctx, (void **)&fs, &capf, 1, sizeof *fs)) return nomem(ps);
    fs[nf].node = root;
    fs[nf++].state = 0;
    while (nf > 0 && !st) {
        frame *f = &fs[nf - 1];
        const node *nd = &ps->nodes[f->node];
        int32_t child = -1;
        as_insn in = {OP_PUSHC, 0, 0.0, 0.0};
        int done = 0;
        term tm = term_of(ps, f->node);
        if (nd->kind == N_CONST) {
            in.c = nd->c;
            done = 1;
        } else if (tm.kind != T_NONE) {
            in.op = OP_PUSH_V + tm.kind;
            in.n = tm.n;
            in.c = tm.c;
            in.d = tm.d;
            if (in.op == OP_PUSH_S && in.c == 0.0 && in.d == 1.0) in.op = OP_PUSH_Q;
            done = 1;
        } else if (nd->kind == N_UN) {
            int32_t a = nd->a;
            in.op = nd->op;
            in.n = nd->n;
            in.c = nd->c;
            const node *an = &ps->nodes[a];
            int32_t y;
            const node *k;
            if (nd->op == OP_SQ && an->kind == N_BIN && (an->op == B_ADD || an->op == B_SUB) &&
                (k = const_operand(ps, an, &y)) != NULL) {
                /* (y + c)^2, (c + y)^2, (y - c)^2 == (y + (-c))^2, (c - y)^2 == (y + (-c))^2 */
                in.op = OP_ADDSQ;
                in.c = an->op == B_ADD ? k->c : -k->c;
                a = y;
            }
            if (f->state == 0)
                child = a;
            else
                done = 1;
        } else {
            plan p = make_plan(ps, nd);
            if (f->state == 0)
                child = p.first;
            else if (f->state == 1 && p.second >= 0)
                child = p.second;
            else {
                in = p.in;
                done = 1;
            }
        }
        if (done) {
            st = emit(ps, in);
            nf--;
        } else {
            f->state++;
            if (as_grow(ps->ctx, (void **)&fs, &capf, nf + 1, sizeof *fs)) {
                st = nomem(ps);
            } else {
                fs[nf].node = child;
                fs[nf++].state = 0;
            }
        }
    }
    as_free(ps->ctx, fs, capf * sizeof *fs);
    return st;
}

/* ---- compiler: the shunting-yard parser ----------------------------------------------- */

static int prec(int k) {
    switch (k) {
    case K_ADD:
    case K_SUB: return 1;
    case K_MUL:
    case K_DIV: return 2;
    case K_NEG: return 3;
    case K_POW: return 4;
    default: return 0; /* brackets */
    }
}

static anistar_status apply_op(parser *ps, const opent *o) {
    switch (o->kind) {
    case K_ADD: return apply_binary(ps, B_ADD, o->pos);
    case K_SUB: return apply_binary(ps, B_SUB, o->pos);
    case K_MUL: return apply_binary(ps, B_MUL, o->pos);
    case K_DIV: return apply_binary(ps, B_DIV, o->pos);
    case K_POW: return apply_binary(ps, B_POW, o->pos);
    case K_NEG: return apply_unary(ps, OP_NEG, 0, 0.0);
    default: return as_fail(ps->ctx, ANISTAR_EINTERNAL, "expression: bad operator");
    }
}

static anistar_status push_op(parser *ps, int kind, size_t pos, int func) {
    if (as_grow(ps->ctx, (void **)&ps->ops, &ps->capops, ps->nops + 1, sizeof *ps->ops))
        return nomem(ps);
    opent *o = &ps->ops[ps->nops++];
    o->kind = kind;
    o->pos = pos;
    o->ppos = pos;
    o->func = func;
    o->nargs = 0;
    return ANISTAR_OK;
}

/* Apply pending operators that bind at least as tightly as an incoming binary operator
 * of precedence p (strictly tighter when it is right associative). */
static anistar_status reduce(parser *ps, int p, int right) {
    while (ps->nops > 0) {
        opent o = ps->ops[ps->nops - 1];
        int q = prec(o.kind);
        if (q == 0 || q < p || (q == p && right)) break;
        ps->nops--;
        anistar_status st = apply_op(ps, &o);
        if (st) return st;
    }
    return ANISTAR_OK;
}

/* The function call at the top of the operator stack has its closing ')' at pos. */
static anistar_status finish_call(parser *ps, size_t pos) {
    opent o = ps->ops[--ps->nops];
    const func_def *f = &FUNCS[o.func];
    size_t got = o.nargs + 1;
    if (f->arity == -2) {
        if (got < 2)
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: function '%s' takes 2 or more arguments, got 1",
                           o.pos + 1, f->name);
        return apply_binary(ps, f->op, pos);
    }
    if (got != (size_t)f->arity)
        return as_fail(ps->ctx, ANISTAR_EFORMAT,
                       "expression, column %zu: function '%s' takes %d argument%s, got %zu",
                       o.pos + 1, f->name, f->arity, f->arity == 1 ? "" : "s", got);
    if (f->arity == 1) return apply_unary(ps, f->op, 0, 0.0);
    return apply_binary(ps, f->op, pos);
}

/* The error for a token that cannot start an operand. */
static anistar_status expected_operand(parser *ps) {
    const tok *t = &ps->cur, *p = &ps->prev;
    char what[64], pw[64];
    describe(ps, t, what, sizeof what);
    describe(ps, p, pw, sizeof pw);
    int pk = p->kind;
    int prev_is_op = pk == T_PLUS || pk == T_MINUS || pk == T_STAR || pk == T_SLASH ||
                     pk == T_CARET;
    if (t->kind == T_END) {
        if (prev_is_op)
            return as_fail(ps->ctx, ANISTAR_EFORMAT, "expression, column %zu: trailing operator %s",
                           p->pos + 1, pw);
        if (pk == T_END) return syntax(ps, 0, "empty expression");
        if (pk == T_SEMI)
            return syntax(ps, t->pos, "expected the formula after the parameter definitions");
        return as_fail(ps->ctx, ANISTAR_EFORMAT,
                       "expression, column %zu: expected an operand after %s, got the end of "
                       "the expression",
                       t->pos + 1, pw);
    }
    if (t->kind == T_RPAREN && pk == T_LPAREN) {
        if (ps->nops > 0 && ps->ops[ps->nops - 1].kind == K_FUNC) {
            const func_def *f = &FUNCS[ps->ops[ps->nops - 1].func];
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: function '%s' takes %s argument%s, got 0",
                           ps->ops[ps->nops - 1].pos + 1, f->name,
                           f->arity == -2 ? "2 or more" : f->arity == 1 ? "1" : "2",
                           f->arity == 1 ? "" : "s");
        }
        return syntax(ps, t->pos, "empty parentheses '()'");
    }
    if ((pk == T_END || pk == T_LPAREN || pk == T_COMMA || pk == T_SEMI || pk == T_EQ) &&
        (t->kind == T_STAR || t->kind == T_SLASH || t->kind == T_CARET))
        return as_fail(ps->ctx, ANISTAR_EFORMAT,
                       "expression, column %zu: operator %s has no left operand", t->pos + 1, what);
    if (pk == T_END) {
        if (t->kind == T_SEMI) return syntax(ps, t->pos, "empty expression before ';'");
        return as_fail(ps->ctx, ANISTAR_EFORMAT, "expression, column %zu: expected an operand, got %s",
                       t->pos + 1, what);
    }
    return as_fail(ps->ctx, ANISTAR_EFORMAT,
                   "expression, column %zu: expected an operand after %s, got %s", t->pos + 1, pw,
                   what);
}

/* A name that is neither a variable, pi, a function nor a known parameter. */
static anistar_status unknown_name(parser *ps, const tok *t) {
    /* Defined later? Look for NAME '=' further on. */
    tok a, b;
    size_t pos = t->pos + t->len;
    anistar_context *keep = ps->ctx;
    ps->ctx = NULL; /* a lexical error further on is not this error */
    for (;;) {
        if (lex_at(ps, pos, &a) || a.kind == T_END) break;
        pos = a.pos + a.len;
        if (a.kind == T_NAME && a.len == t->len && memcmp(ps->src + a.pos, ps->src + t->pos, t->len) == 0) {
            if (lex_at(ps, pos, &b)) break;
            if (b.kind == T_EQ) {
                ps->ctx = keep;
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: parameter '%.*s' is used before its "
                               "definition at column %zu",
                               t->pos + 1, show_len(t->len), ps->src + t->pos, a.pos + 1);
            }
        }
    }
    ps->ctx = keep;
    return as_fail(ps->ctx, ANISTAR_EFORMAT,
                   "expression, column %zu: unknown name '%.*s' (the variables are x, y, z)",
                   t->pos + 1, show_len(t->len), ps->src + t->pos);
}

/* An operand that is a name (the current token). Sets *call when it opens a call. */
static anistar_status name_operand(parser *ps, int *call) {
    const tok *t = &ps->cur;
    const char *nm = ps->src + t->pos;
    int nl = show_len(t->len);
    tok nx;
    anistar_status st = lex_at(ps, t->pos + t->len, &nx);
    if (st) return st;
    int f = find_func(ps, t);
    *call = 0;
    if (nx.kind == T_LPAREN) {
        if (f < 0) {
            if (is_reserved(ps, t) || find_param(ps, t) >= 0)
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: '%.*s' is not a function", t->pos + 1, nl,
                               nm);
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: unknown function '%.*s' (known: " AS_EXPR_KNOWN_FUNCS
                           ")",
                           t->pos + 1, nl, nm);
        }
        *call = 1;
        st = push_op(ps, K_FUNC, t->pos, f);
        if (st) return st;
        st = advance(ps); /* now at '(' */
        ps->ops[ps->nops - 1].ppos = ps->cur.pos;
        return st;
    }
    if (f >= 0)
        return as_fail(ps->ctx, ANISTAR_EFORMAT,
                       "expression, column %zu: function '%s' needs its arguments in parentheses",
                       t->pos + 1, FUNCS[f].name);
    int var = tok_is(ps, t, "x") ? 0 : tok_is(ps, t, "y") ? 1 : tok_is(ps, t, "z") ? 2 : -1;
    if (var >= 0) {
        if (ps->in_param)
            return as_fail(ps->ctx, ANISTAR_EFORMAT,
                           "expression, column %zu: parameter '%.*s' cannot use the variable '%c' "
                           "(parameters are constants)",
                           t->pos + 1, show_len(ps->pnamelen), ps->src + ps->pname, "xyz"[var]);
        return push_var(ps, var);
    }
    if (tok_is(ps, t, "pi")) return push_const(ps, AS_EXPR_PI);
    long k = find_param(ps, t);
    if (k >= 0) return push_const(ps, ps->params[k].value);
    return unknown_name(ps, t);
}

/* Parse one statement's expression, up to ';' or the end at parenthesis depth 0; leaves
 * one node on the operand stack and the ';' or end as the current token. */
static anistar_status parse_expr(parser *ps) {
    anistar_status st = ANISTAR_OK;
    int want_operand = 1;
    size_t base = ps->nops;
    for (;;) {
        const tok t = ps->cur;
        if (want_operand) {
            int call = 0;
            switch (t.kind) {
            case T_NUM: st = push_const(ps, t.num); want_operand = 0; break;
            case T_NAME:
                st = name_operand(ps, &call);
                want_operand = call;
                break;
            case T_MINUS: st = push_op(ps, K_NEG, t.pos, 0); break;
            case T_PLUS: st = ANISTAR_OK; break;
            case T_LPAREN: st = push_op(ps, K_PAREN, t.pos, 0); break;
            default: return expected_operand(ps);
            }
        } else {
            int k = -1;
            switch (t.kind) {
            case T_PLUS: k = K_ADD; break;
            case T_MINUS: k = K_SUB; break;
            case T_STAR: k = K_MUL; break;
            case T_SLASH: k = K_DIV; break;
            case T_CARET: k = K_POW; break;
            default: break;
            }
            if (k >= 0) {
                st = reduce(ps, prec(k), k == K_POW);
                if (!st) st = push_op(ps, k, t.pos, 0);
                want_operand = 1;
            } else if (t.kind == T_RPAREN || t.kind == T_COMMA) {
                st = reduce(ps, 1, 0);
                if (st) return st;
                if (ps->nops == base) {
                    if (t.kind == T_RPAREN) return syntax(ps, t.pos, "unmatched ')'");
                    return syntax(ps, t.pos, "',' outside of a function's arguments");
                }
                opent *o = &ps->ops[ps->nops - 1];
                if (t.kind == T_RPAREN) {
                    if (o->kind == K_PAREN) {
                        ps->nops--;
                    } else {
                        st = finish_call(ps, t.pos);
                    }
                } else {
                    if (o->kind != K_FUNC)
                        return syntax(ps, t.pos, "',' outside of a function's arguments");
                    o->nargs++;
                    /* min and max fold as they go, so long argument lists need no stack */
                    if (FUNCS[o->func].arity == -2 && o->nargs >= 2)
                        st = apply_binary(ps, FUNCS[o->func].op, t.pos);
                    want_operand = 1;
                }
            } else if (t.kind == T_SEMI || t.kind == T_END) {
                st = reduce(ps, 1, 0);
                if (st) return st;
                if (ps->nops > base) {
                    const opent *o = &ps->ops[ps->nops - 1];
                    char what[64];
                    describe(ps, &t, what, sizeof what);
                    return as_fail(ps->ctx, ANISTAR_EFORMAT,
                                   "expression, column %zu: expected ')' to close '(' at column "
                                   "%zu, got %s",
                                   t.pos + 1, o->ppos + 1, what);
                }
                return ANISTAR_OK;
            } else if (t.kind == T_EQ) {
                return syntax(ps, t.pos,
                              "unexpected '=' (parameters are defined before the formula: NAME = "
                              "VALUE;)");
            } else {
                char what[64], pw[64];
                describe(ps, &t, what, sizeof what);
                describe(ps, &ps->prev, pw, sizeof pw);
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: missing operator between %s and %s",
                               t.pos + 1, pw, what);
            }
        }
        if (st) return st;
        st = advance(ps);
        if (st) return st;
    }
}

/* ---- compiler: driver ------------------------------------------------------------------ */

static int stack_effect(int op) {
    switch (op) {
    case OP_PUSHC:
    case OP_PUSH_V:
    case OP_PUSH_L:
    case OP_PUSH_S:
    case OP_PUSH_Q: return 1;
    case OP_ADD:
    case OP_SUB:
    case OP_RSUB:
    case OP_MUL:
    case OP_DIV:
    case OP_RDIV:
    case OP_POW:
    case OP_ATAN2:
    case OP_MIN:
    case OP_MAX: return -1;
    default: return 0;
    }
}

static anistar_status parse_program(parser *ps) {
    anistar_status st = lex_at(ps, 0, &ps->cur);
    if (st) return st;
    ps->prev.kind = T_END;
    ps->prev.pos = 0;
    ps->prev.len = 0;
    for (;;) {
        tok nx;
        if (ps->cur.kind == T_NAME) {
            st = lex_at(ps, ps->cur.pos + ps->cur.len, &nx);
            if (st) return st;
        } else {
            nx.kind = T_END;
        }
        if (ps->cur.kind == T_NAME && nx.kind == T_EQ) {
            const tok name = ps->cur;
            if (is_reserved(ps, &name))
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: '%.*s' is reserved and cannot be a parameter",
                               name.pos + 1, show_len(name.len), ps->src + name.pos);
            long old = find_param(ps, &name);
            if (old >= 0)
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: parameter '%.*s' is already defined at "
                               "column %zu",
                               name.pos + 1, show_len(name.len), ps->src + name.pos,
                               ps->params[old].pos + 1);
            ps->in_param = 1;
            ps->pname = name.pos;
            ps->pnamelen = name.len;
            if ((st = advance(ps)) || (st = advance(ps))) return st;
            st = parse_expr(ps);
            if (st) return st;
            if (ps->cur.kind != T_SEMI)
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: expected ';' after the definition of "
                               "parameter '%.*s', then the formula",
                               ps->cur.pos + 1, show_len(name.len), ps->src + name.pos);
            const node *d = &ps->nodes[ps->vs[--ps->nvs]];
            if (d->kind != N_CONST || ps->nvs != 0)
                return as_fail(ps->ctx, ANISTAR_EINTERNAL,
                               "expression: parameter '%.*s' did not fold to a constant",
                               show_len(name.len), ps->src + name.pos);
            double v = d->c;
            if (!isfinite(v))
                return as_fail(ps->ctx, ANISTAR_EFORMAT,
                               "expression, column %zu: parameter '%.*s' is not a finite number "
                               "(%g)",
                               name.pos + 1, show_len(name.len), ps->src + name.pos, v);
            if (as_grow(ps->ctx, (void **)&ps->params, &ps->capparams, ps->nparams + 1,
                        sizeof *ps->params))
                return nomem(ps);
            pparam *pp = &ps->params[ps->nparams++];
            pp->pos = name.pos;
            pp->len = name.len;
            pp->value = v;
            ps->in_param = 0;
            st = advance(ps);
            if (st) return st;
            continue;
        }
        st = parse_expr(ps);
        if (st) return st;
        if (ps->nvs != 1)
            return as_fail(ps->ctx, ANISTAR_EINTERNAL, "expression: operand stack out of step");
        if (ps->cur.kind == T_SEMI) {
            st = advance(ps);
            if (st) return st;
            if (ps->cur.kind != T_END)
                return syntax(ps, ps->cur.pos,
                              "unexpected text after the formula (parameter definitions come "
                              "first, the formula last)");
        }
        return ANISTAR_OK;
    }
}

static size_t align8(size_t n) { return (n + 7u) & ~(size_t)7u; }

/* Copy the compiled program into one block. */
static anistar_status finish(parser *ps, as_expr **out) {
    int depth = 0, maxd = 0, uses = 0;
    /* the code ends with one OP_END */
    if (ps->ncode < 2 || ps->code[ps->ncode - 1].op != OP_END)
        return as_fail(ps->ctx, ANISTAR_EINTERNAL, "expression: inconsistent bytecode");
    for (size_t i = 0; i + 1 < ps->ncode; i++) {
        const as_insn *in = &ps->code[i];
        depth += stack_effect(in->op);
        if (depth < 1 || in->op < 0 || in->op >= OP_END)
            return as_fail(ps->ctx, ANISTAR_EINTERNAL, "expression: inconsistent bytecode");
        if (depth > maxd) maxd = depth;
        if (in->op >= OP_PUSH_V && in->op != OP_END) uses |= 1 << in->n;
    }
    if (depth != 1 || maxd > AS_EXPR_MAX_STACK || maxd != ps->nodes[ps->vs[0]].need)
        return as_fail(ps->ctx, ANISTAR_EINTERNAL, "expression: inconsistent bytecode");
    size_t names = 0;
    for (size_t i = 0; i < ps->nparams; i++) names += ps->params[i].len + 1;
    size_t off_code = align8(sizeof(as_expr));
    size_t bytes_code, bytes_par;
    if (as_mul_size(ps->ncode, sizeof(as_insn), &bytes_code) ||
        as_mul_size(ps->nparams, sizeof(as_param), &bytes_par))
        return nomem(ps);
    size_t off_par = off_code + bytes_code;
    size_t off_names = off_par + bytes_par;
    size_t bytes = off_names + names;
    if (bytes < off_names) return nomem(ps);
    char *blk = as_alloc(ps->ctx, bytes);
    if (!blk) return nomem(ps);
    as_expr *e = (as_expr *)(void *)blk;
    as_insn *code = (as_insn *)(void *)(blk + off_code);
    as_param *par = (as_param *)(void *)(blk + off_par);
    char *nm = blk + off_names;
    memcpy(code, ps->code, bytes_code);
    size_t at = 0;
    for (size_t i = 0; i < ps->nparams; i++) {
        par[i].name = at;
        par[i].value = ps->params[i].value;
        memcpy(nm + at, ps->src + ps->params[i].pos, ps->params[i].len);
        at += ps->params[i].len;
        nm[at++] = '\0';
    }
    e->bytes = bytes;
    e->ncode = ps->ncode - 1; /* without OP_END */
    e->code = code;
    e->nparams = ps->nparams;
    e->params = par;
    e->names = nm;
    e->max_stack = maxd;
    e->uses = uses;
    *out = e;
    return ANISTAR_OK;
}

/*
 * as_expr_compile — parse src and produce its bytecode.
 * Returns ANISTAR_OK and *out; ANISTAR_EFORMAT with "expression, column N: ..." on a
 * syntax error; ANISTAR_ENOMEM; ANISTAR_EINVAL for NULL arguments.
 * Notes: no recursion (a shunting-yard parser with explicit, heap-allocated stacks), so
 *   nesting depth is limited only by memory and by the evaluation stack (operands that
 *   stay pending at once, at most AS_EXPR_MAX_STACK).
 * design:
 *   1. for each `NAME = EXPR ;` compile EXPR (which folds to a constant) and record it;
 *   2. compile the formula, folding constants and fusing operands as they are emitted;
 *   3. check the stack depth and copy code, parameters and names into one block.
 */
anistar_status as_expr_compile(anistar_context *ctx, const char *src, as_expr **out) {
    if (out) *out = NULL;
    if (!ctx || !src || !out)
        return as_fail(ctx, ANISTAR_EINVAL, "as_expr_compile: NULL argument");
    parser ps;
    memset(&ps, 0, sizeof ps);
    ps.ctx = ctx;
    ps.src = src;
    ps.srclen = strlen(src);
    anistar_status st = ANISTAR_OK;
    if (ps.srclen > AS_EXPR_MAX_LENGTH)
        st = as_fail(ctx, ANISTAR_EFORMAT, "expression: longer than %d characters",
                     AS_EXPR_MAX_LENGTH);
    if (!st) st = parse_program(&ps);
    if (!st) st = gen_code(&ps, ps.vs[0]);
    if (!st) {
        as_insn end = {OP_END, 0, 0.0, 0.0};
        st = emit(&ps, end);
    }
    if (!st) st = finish(&ps, out);
    as_free(ctx, ps.nodes, ps.capnodes * sizeof *ps.nodes);
    as_free(ctx, ps.vs, ps.capvs * sizeof *ps.vs);
    as_free(ctx, ps.code, ps.capcode * sizeof *ps.code);
    as_free(ctx, ps.ops, ps.capops * sizeof *ps.ops);
    as_free(ctx, ps.params, ps.capparams * sizeof *ps.params);
    return st;
}

void as_expr_free(anistar_context *ctx, as_expr *e) {
    if (e) as_free(ctx, e, e->bytes);
}

int as_expr_param(const as_expr *e, const char *name, double *v) {
    if (!e || !name) return -1;
    for (size_t i = 0; i < e->nparams; i++)
        if (strcmp(e->names + e->params[i].name, name) == 0) {
            if (v) *v = e->params[i].value;
            return 0;
        }
    return -1;
}

size_t as_expr_param_count(const as_expr *e) { return e ? e->nparams : 0; }

int as_expr_param_at(const as_expr *e, size_t i, const char **name, double *v) {
    if (!e || i >= e->nparams) return -1;
    if (name) *name = e->names + e->params[i].name;
    if (v) *v = e->params[i].value;
    return 0;
}

int as_expr_uses_xyz(const as_expr *e) { return e ? e->uses : 0; }

int as_expr_has_kinks(const as_expr *e) {
    if (!e) return 0;
    for (size_t i = 0; i < e->ncode; i++) {
        int op = e->code[i].op;
        if (op == OP_ABS || op == OP_MIN || op == OP_MAX) return 1;
    }
    return 0;
}

int as_expr_stack_depth(const as_expr *e) { return e ? e->max_stack : 0; }

size_t as_expr_code_size(const as_expr *e) { return e ? e->ncode : 0; }

/* ---- evaluation: value ---------------------------------------------------------------- */

/* The value of the term of instruction in (kind T_V, T_L or T_S) at p. */
static inline double term_value(int kind, const as_insn *in, const double p[3]) {
    double v = p[in->n];
    if (kind == T_V) return in->d * v;
    double u = v + in->c;
    return kind == T_L ? in->d * u : in->d * (u * u);
}

/*
 * as_expr_value — the value at p.
 * Notes: reentrant (the stack is a local array of e->max_stack <= AS_EXPR_MAX_STACK
 *   doubles); the top of the stack lives in t, s points past the last spilled element.
 */
double as_expr_value(const as_expr *e, const double p[3]) {
    double st[AS_EXPR_MAX_STACK];
    double *s = st;
    double t = 0.0, u;
    for (const as_insn *ip = e->code;; ip++) {
        switch (ip->op) {
        case OP_END: return t;
        case OP_PUSHC: *s++ = t; t = ip->c; break;
        case OP_NEG: t = -t; break;
        case OP_SQ: t = t * t; break;
        case OP_ADDSQ: u = t + ip->c; t = u * u; break;
        case OP_POWI: t = v_powi(t, ip->n); break;
        case OP_POWC: t = v_pow(t, ip->c); break;
        case OP_SQRT: t = sqrt(t); break;
        case OP_EXP: t = exp(t); break;
        case OP_LOG: t = log(t); break;
        case OP_SIN: t = sin(t); break;
        case OP_COS: t = cos(t); break;
        case OP_TAN: t = tan(t); break;
        case OP_TANH: t = tanh(t); break;
        case OP_ABS: t = fabs(t); break;
        case OP_ADD: t = *--s + t; break;
        case OP_SUB: t = *--s - t; break;
        case OP_RSUB: t = t - *--s; break;
        case OP_MUL: t = *--s * t; break;
        case OP_DIV: u = *--s; t = v_div(u, t); break;
        case OP_RDIV: t = v_div(t, *--s); break;
        case OP_POW: u = *--s; t = v_pow(u, t); break;
        case OP_ATAN2: u = *--s; t = atan2(u, t); break;
        case OP_MIN: u = *--s; t = v_min(u, t); break;
        case OP_MAX: u = *--s; t = v_max(u, t); break;
        case OP_ADDC: t = t + ip->c; break;
        case OP_MULC: t = t * ip->c; break;
        case OP_DIVC: t = v_div(t, ip->c); break;
        case OP_RSUBC: t = ip->c - t; break;
        case OP_RDIVC: t = v_div(ip->c, t); break;
        case OP_PUSH_V: *s++ = t; t = term_value(T_V, ip, p); break;
        case OP_PUSH_L: *s++ = t; t = term_value(T_L, ip, p); break;
        case OP_PUSH_S: *s++ = t; t = term_value(T_S, ip, p); break;
        case OP_ADD_V: t = t + term_value(T_V, ip, p); break;
        case OP_ADD_L: t = t + term_value(T_L, ip, p); break;
        case OP_ADD_S: t = t + term_value(T_S, ip, p); break;
        case OP_RSUB_V: t = term_value(T_V, ip, p) - t; break;
        case OP_RSUB_L: t = term_value(T_L, ip, p) - t; break;
        case OP_RSUB_S: t = term_value(T_S, ip, p) - t; break;
        case OP_MUL_V: t = t * term_value(T_V, ip, p); break;
        case OP_MUL_L: t = t * term_value(T_L, ip, p); break;
        case OP_MUL_S: t = t * term_value(T_S, ip, p); break;
        case OP_PUSH_Q: *s++ = t; t = p[ip->n] * p[ip->n]; break;
        case OP_ADD_Q: t = t + p[ip->n] * p[ip->n]; break;
        default: return NAN;
        }
    }
}

/* ---- derivatives of the elementary functions ----------------------------------------- */

/* A unary function's value, first and second derivative at u. */
typedef struct d3 {
    double f, d1, d2;
} d3;

static inline d3 unary_derivs(int op, double u, const as_insn *in) {
    d3 r;
    switch (op) {
    case OP_SQ:
        r.f = u * u;
        r.d1 = 2.0 * u;
        r.d2 = 2.0;
        break;
    case OP_ADDSQ: {
        double w = u + in->c;
        r.f = w * w;
        r.d1 = 2.0 * w;
        r.d2 = 2.0;
        break;
    }
    case OP_POWI: {
        int n = in->n;
        double dn = (double)n;
        r.f = v_powi(u, n);
        r.d1 = dn * v_powi(u, n - 1);
        r.d2 = dn * (dn - 1.0) * v_powi(u, n - 2);
        break;
    }
    case OP_POWC: {
        double c = in->c;
        r.f = v_pow(u, c);
        if (u != 0.0) {
            r.d1 = c * r.f / u;
            r.d2 = (c - 1.0) * r.d1 / u;
        } else {
            r.d1 = c * v_pow(u, c - 1.0);
            r.d2 = c * (c - 1.0) * v_pow(u, c - 2.0);
        }
        break;
    }
    case OP_SQRT:
        r.f = sqrt(u);
        r.d1 = 0.5 / r.f;
        r.d2 = -0.5 * r.d1 / u;
        break;
    case OP_EXP: r.f = r.d1 = r.d2 = exp(u); break;
    case OP_LOG:
        r.f = log(u);
        r.d1 = 1.0 / u;
        r.d2 = -r.d1 * r.d1;
        break;
    case OP_SIN:
        r.f = sin(u);
        r.d1 = cos(u);
        r.d2 = -r.f;
        break;
    case OP_COS:
        r.f = cos(u);
        r.d1 = -sin(u);
        r.d2 = -r.f;
        break;
    case OP_TAN:
        r.f = tan(u);
        r.d1 = 1.0 + r.f * r.f;
        r.d2 = 2.0 * r.f * r.d1;
        break;
    case OP_TANH:
        r.f = tanh(u);
        r.d1 = 1.0 - r.f * r.f;
        r.d2 = -2.0 * r.f * r.d1;
        break;
    default: r.f = r.d1 = r.d2 = NAN; break;
    }
    return r;
}

/* A binary function's value and partial derivatives at (a, b). */
typedef struct d6 {
    double f, fa, fb, faa, fab, fbb;
} d6;

static inline d6 pow_derivs(double a, double b) {
    d6 r;
    r.f = v_pow(a, b);
    double pa1 = v_pow(a, b - 1.0);
    r.fa = b * pa1;
    r.faa = b * (b - 1.0) * v_pow(a, b - 2.0);
    if (a == 0.0) { /* 0^b == 0 for every b > 0: no dependence on b (right limits) */
        r.fb = 0.0;
        r.fbb = 0.0;
        r.fab = b > 1.0 ? 0.0 : -INFINITY;
    } else {
        double la = log(a); /* NaN for a < 0: a^b is undefined for nearby b */
        r.fb = r.f * la;
        r.fbb = r.fb * la;
        r.fab = pa1 * (1.0 + b * la);
    }
    return r;
}

static inline d6 atan2_derivs(double a, double b) {
    d6 r;
    r.f = atan2(a, b);
    double r2 = a * a + b * b;
    double i2 = 1.0 / r2, i4 = i2 * i2;
    r.fa = b * i2;
    r.fb = -a * i2;
    r.faa = -2.0 * a * b * i4;
    r.fbb = 2.0 * a * b * i4;
    r.fab = (a * a - b * b) * i4;
    return r;
}

/* A term's value and first and second derivative with respect to its variable. */
typedef struct tder {
    double f, g, h;
} tder;

static inline tder term_derivs(int kind, const as_insn *in, const double p[3]) {
    tder r;
    double v = p[in->n];
    if (kind == T_S) {
        double u = v + in->c;
        r.f = in->d * (u * u);
        r.g = 2.0 * in->d * u;
        r.h = 2.0 * in->d;
    } else {
        r.f = kind == T_V ? in->d * v : in->d * (v + in->c);
        r.g = in->d;
        r.h = 0.0;
    }
    return r;
}

/* ---- evaluation: value and gradient ------------------------------------------------------ */

typedef struct gd {
    double f, g[3];
} gd;

static inline void g_chain(gd *u, d3 d) {
    u->f = d.f;
    for (int i = 0; i < 3; i++) u->g[i] *= d.d1;
}
static inline void g_bin(gd *a, const gd *b, const d6 *d) {
    for (int i = 0; i < 3; i++) a->g[i] = d->fa * a->g[i] + d->fb * b->g[i];
    a->f = d->f;
}
static inline void g_add(gd *a, const gd *b) {
    a->f = a->f + b->f;
    for (int i = 0; i < 3; i++) a->g[i] = a->g[i] + b->g[i];
}
static inline void g_sub(gd *a, const gd *b) {
    a->f = a->f - b->f;
    for (int i = 0; i < 3; i++) a->g[i] = a->g[i] - b->g[i];
}
static inline void g_mul(gd *a, const gd *b) {
    for (int i = 0; i < 3; i++) a->g[i] = b->f * a->g[i] + a->f * b->g[i];
    a->f = a->f * b->f;
}
/* a <- q = a/b: gq = (ga - q gb)/b. */
static inline void g_div(gd *a, const gd *b) {
    double q = v_div(a->f, b->f), ib = 1.0 / b->f;
    for (int i = 0; i < 3; i++) a->g[i] = (a->g[i] - q * b->g[i]) * ib;
    a->f = q;
}
static inline void g_neg(gd *a) {
    a->f = -a->f;
    for (int i = 0; i < 3; i++) a->g[i] = -a->g[i];
}
static inline void g_scale(gd *a, double c) {
    a->f = a->f * c;
    for (int i = 0; i < 3; i++) a->g[i] *= c;
}
static inline void g_pick(gd *a, const gd *b, int which) {
    if (which == 1) *a = *b;
    else if (which < 0) a->f = NAN;
}
static inline gd g_const(double c) {
    gd r = {c, {0.0, 0.0, 0.0}};
    return r;
}
static inline gd g_term(int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    gd r = g_const(d.f);
    r.g[in->n] = d.g;
    return r;
}
static inline void g_add_term(gd *t, int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    t->f = t->f + d.f;
    t->g[in->n] += d.g;
}
static inline void g_rsub_term(gd *t, int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    double f = t->f;
    g_neg(t);
    t->f = d.f - f;
    t->g[in->n] += d.g;
}
static inline void g_mul_term(gd *t, int kind, const as_insn *in, const double p[3]) {
    gd k = g_term(kind, in, p);
    g_mul(t, &k);
}

/*
 * as_expr_value_grad — value and gradient at p by forward-mode differentiation (each
 * stack slot carries f and its gradient). The value is bitwise that of as_expr_value.
 */
double as_expr_value_grad(const as_expr *e, const double p[3], double g[3]) {
    gd st[AS_EXPR_MAX_STACK + 1]; /* st[0] is never used: s - 1 stays inside */
    gd *s = st + 1;               /* s[-1] is the top */
    gd k;
    double u;
    for (const as_insn *ip = e->code;; ip++) {
        gd *t = s - 1;
        switch (ip->op) {
        case OP_END:
            for (int i = 0; i < 3; i++) g[i] = st[1].g[i];
            return st[1].f;
        case OP_PUSHC: *s++ = g_const(ip->c); break;
        case OP_NEG: g_neg(t); break;
        case OP_SQ:
        case OP_ADDSQ:
        case OP_POWI:
        case OP_POWC:
        case OP_SQRT:
        case OP_EXP:
        case OP_LOG:
        case OP_SIN:
        case OP_COS:
        case OP_TAN:
        case OP_TANH: g_chain(t, unary_derivs(ip->op, t->f, ip)); break;
        case OP_ABS: /* at 0 the branch +u (derivative +1) */
            if (t->f < 0.0) g_neg(t);
            t->f = fabs(t->f);
            break;
        case OP_ADD: s--; g_add(t - 1, t); break;
        case OP_SUB: s--; g_sub(t - 1, t); break;
        case OP_RSUB: s--; k = *t; g_sub(&k, t - 1); t[-1] = k; break;
        case OP_MUL: s--; g_mul(t - 1, t); break;
        case OP_DIV: s--; g_div(t - 1, t); break;
        case OP_RDIV: s--; k = *t; g_div(&k, t - 1); t[-1] = k; break;
        case OP_POW: {
            s--;
            d6 d = pow_derivs(t[-1].f, t->f);
            g_bin(t - 1, t, &d);
            break;
        }
        case OP_ATAN2: {
            s--;
            d6 d = atan2_derivs(t[-1].f, t->f);
            g_bin(t - 1, t, &d);
            break;
        }
        case OP_MIN: s--; g_pick(t - 1, t, pick_min(t[-1].f, t->f)); break;
        case OP_MAX: s--; g_pick(t - 1, t, pick_max(t[-1].f, t->f)); break;
        case OP_ADDC: t->f = t->f + ip->c; break;
        case OP_MULC: g_scale(t, ip->c); break;
        case OP_DIVC: k = g_const(ip->c); g_div(t, &k); break;
        case OP_RSUBC: u = t->f; g_neg(t); t->f = ip->c - u; break;
        case OP_RDIVC: k = g_const(ip->c); g_div(&k, t); *t = k; break;
        case OP_PUSH_V: *s++ = g_term(T_V, ip, p); break;
        case OP_PUSH_L: *s++ = g_term(T_L, ip, p); break;
        case OP_PUSH_S:
        case OP_PUSH_Q: *s++ = g_term(T_S, ip, p); break;
        case OP_ADD_V: g_add_term(t, T_V, ip, p); break;
        case OP_ADD_L: g_add_term(t, T_L, ip, p); break;
        case OP_ADD_S:
        case OP_ADD_Q: g_add_term(t, T_S, ip, p); break;
        case OP_RSUB_V: g_rsub_term(t, T_V, ip, p); break;
        case OP_RSUB_L: g_rsub_term(t, T_L, ip, p); break;
        case OP_RSUB_S: g_rsub_term(t, T_S, ip, p); break;
        case OP_MUL_V: g_mul_term(t, T_V, ip, p); break;
        case OP_MUL_L: g_mul_term(t, T_L, ip, p); break;
        case OP_MUL_S: g_mul_term(t, T_S, ip, p); break;
        default: g[0] = g[1] = g[2] = NAN; return NAN;
        }
    }
}

/* ---- evaluation: value, gradient and Hessian --------------------------------------------- */

/* h: the symmetric Hessian as m11 m12 m13 m22 m23 m33. */
typedef struct hd {
    double f, g[3], h[6];
} hd;

static const int HI[6] = {0, 0, 0, 1, 1, 2};
static const int HJ[6] = {0, 1, 2, 1, 2, 2};
static const int HDIAG[3] = {0, 3, 5};

/* u <- phi(u): H = phi' H + phi'' g g^T, g = phi' g. */
static inline void h_chain(hd *u, d3 d) {
    for (int k = 0; k < 6; k++) u->h[k] = d.d1 * u->h[k] + d.d2 * (u->g[HI[k]] * u->g[HJ[k]]);
    for (int i = 0; i < 3; i++) u->g[i] *= d.d1;
    u->f = d.f;
}

/* a <- F(a, b): H = Fa Ha + Fb Hb + Faa ga ga^T + Fab (ga gb^T + gb ga^T) + Fbb gb gb^T. */
static inline void h_bin(hd *a, const hd *b, const d6 *d) {
    for (int k = 0; k < 6; k++) {
        int i = HI[k], j = HJ[k];
        a->h[k] = d->fa * a->h[k] + d->fb * b->h[k] + d->faa * (a->g[i] * a->g[j]) +
                  d->fab * (a->g[i] * b->g[j] + b->g[i] * a->g[j]) +
                  d->fbb * (b->g[i] * b->g[j]);
    }
    for (int i = 0; i < 3; i++) a->g[i] = d->fa * a->g[i] + d->fb * b->g[i];
    a->f = d->f;
}

static inline void h_add(hd *a, const hd *b) {
    a->f = a->f + b->f;
    for (int i = 0; i < 3; i++) a->g[i] = a->g[i] + b->g[i];
    for (int k = 0; k < 6; k++) a->h[k] = a->h[k] + b->h[k];
}
static inline void h_sub(hd *a, const hd *b) {
    a->f = a->f - b->f;
    for (int i = 0; i < 3; i++) a->g[i] = a->g[i] - b->g[i];
    for (int k = 0; k < 6; k++) a->h[k] = a->h[k] - b->h[k];
}
static inline void h_neg(hd *a) {
    a->f = -a->f;
    for (int i = 0; i < 3; i++) a->g[i] = -a->g[i];
    for (int k = 0; k < 6; k++) a->h[k] = -a->h[k];
}
/* a <- a*b: H = b Ha + a Hb + ga gb^T + gb ga^T. */
static inline void h_mul(hd *a, const hd *b) {
    for (int k = 0; k < 6; k++) {
        int i = HI[k], j = HJ[k];
        a->h[k] = b->f * a->h[k] + a->f * b->h[k] + (a->g[i] * b->g[j] + b->g[i] * a->g[j]);
    }
    for (int i = 0; i < 3; i++) a->g[i] = b->f * a->g[i] + a->f * b->g[i];
    a->f = a->f * b->f;
}
/* a <- q = a/b: gq = (ga - q gb)/b, Hq = (Ha - q Hb - gq gb^T - gb gq^T)/b. */
static inline void h_div(hd *a, const hd *b) {
    double q = v_div(a->f, b->f), ib = 1.0 / b->f;
    for (int i = 0; i < 3; i++) a->g[i] = (a->g[i] - q * b->g[i]) * ib;
    for (int k = 0; k < 6; k++) {
        int i = HI[k], j = HJ[k];
        a->h[k] = (a->h[k] - q * b->h[k] - (a->g[i] * b->g[j] + b->g[i] * a->g[j])) * ib;
    }
    a->f = q;
}
static inline void h_scale(hd *a, double c) {
    a->f = a->f * c;
    for (int i = 0; i < 3; i++) a->g[i] *= c;
    for (int k = 0; k < 6; k++) a->h[k] *= c;
}
static inline void h_pick(hd *a, const hd *b, int which) {
    if (which == 1) *a = *b;
    else if (which < 0) a->f = NAN;
}
static inline hd h_const(double c) {
    hd r = {c, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0, 0.0, 0.0, 0.0}};
    return r;
}
static inline hd h_term(int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    hd r = h_const(d.f);
    r.g[in->n] = d.g;
    r.h[HDIAG[in->n]] = d.h;
    return r;
}
static inline void h_add_term(hd *t, int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    t->f = t->f + d.f;
    t->g[in->n] += d.g;
    t->h[HDIAG[in->n]] += d.h;
}
static inline void h_rsub_term(hd *t, int kind, const as_insn *in, const double p[3]) {
    tder d = term_derivs(kind, in, p);
    double f = t->f;
    h_neg(t);
    t->f = d.f - f;
    t->g[in->n] += d.g;
    t->h[HDIAG[in->n]] += d.h;
}
static inline void h_mul_term(hd *t, int kind, const as_insn *in, const double p[3]) {
    hd k = h_term(kind, in, p);
    h_mul(t, &k);
}

/*
 * as_expr_value_grad_hess — value, gradient and Hessian at p by forward-mode
 * differentiation to second order (each stack slot carries f, its gradient and its
 * Hessian). Value and gradient are bitwise those of as_expr_value_grad.
 */
double as_expr_value_grad_hess(const as_expr *e, const double p[3], double g[3], double h[6]) {
    hd st[AS_EXPR_MAX_STACK + 1]; /* st[0] is never used: s - 1 stays inside */
    hd *s = st + 1;               /* s[-1] is the top */
    hd k;
    double u;
    for (const as_insn *ip = e->code;; ip++) {
        hd *t = s - 1;
        switch (ip->op) {
        case OP_END:
            for (int i = 0; i < 3; i++) g[i] = st[1].g[i];
            for (int i = 0; i < 6; i++) h[i] = st[1].h[i];
            return st[1].f;
        case OP_PUSHC: *s++ = h_const(ip->c); break;
        case OP_NEG: h_neg(t); break;
        case OP_SQ:
        case OP_ADDSQ:
        case OP_POWI:
        case OP_POWC:
        case OP_SQRT:
        case OP_EXP:
        case OP_LOG:
        case OP_SIN:
        case OP_COS:
        case OP_TAN:
        case OP_TANH: h_chain(t, unary_derivs(ip->op, t->f, ip)); break;
        case OP_ABS: /* at 0 the branch +u */
            if (t->f < 0.0) h_neg(t);
            t->f = fabs(t->f);
            break;
        case OP_ADD: s--; h_add(t - 1, t); break;
        case OP_SUB: s--; h_sub(t - 1, t); break;
        case OP_RSUB: s--; k = *t; h_sub(&k, t - 1); t[-1] = k; break;
        case OP_MUL: s--; h_mul(t - 1, t); break;
        case OP_DIV: s--; h_div(t - 1, t); break;
        case OP_RDIV: s--; k = *t; h_div(&k, t - 1); t[-1] = k; break;
        case OP_POW: {
            s--;
            d6 d = pow_derivs(t[-1].f, t->f);
            h_bin(t - 1, t, &d);
            break;
        }
        case OP_ATAN2: {
            s--;
            d6 d = atan2_derivs(t[-1].f, t->f);
            h_bin(t - 1, t, &d);
            break;
        }
        case OP_MIN: s--; h_pick(t - 1, t, pick_min(t[-1].f, t->f)); break;
        case OP_MAX: s--; h_pick(t - 1, t, pick_max(t[-1].f, t->f)); break;
        case OP_ADDC: t->f = t->f + ip->c; break;
        case OP_MULC: h_scale(t, ip->c); break;
        case OP_DIVC: k = h_const(ip->c); h_div(t, &k); break;
        case OP_RSUBC: u = t->f; h_neg(t); t->f = ip->c - u; break;
        case OP_RDIVC: k = h_const(ip->c); h_div(&k, t); *t = k; break;
        case OP_PUSH_V: *s++ = h_term(T_V, ip, p); break;
        case OP_PUSH_L: *s++ = h_term(T_L, ip, p); break;
        case OP_PUSH_S:
        case OP_PUSH_Q: *s++ = h_term(T_S, ip, p); break;
        case OP_ADD_V: h_add_term(t, T_V, ip, p); break;
        case OP_ADD_L: h_add_term(t, T_L, ip, p); break;
        case OP_ADD_S:
        case OP_ADD_Q: h_add_term(t, T_S, ip, p); break;
        case OP_RSUB_V: h_rsub_term(t, T_V, ip, p); break;
        case OP_RSUB_L: h_rsub_term(t, T_L, ip, p); break;
        case OP_RSUB_S: h_rsub_term(t, T_S, ip, p); break;
        case OP_MUL_V: h_mul_term(t, T_V, ip, p); break;
        case OP_MUL_L: h_mul_term(t, T_L, ip, p); break;
        case OP_MUL_S: h_mul_term(t, T_S, ip, p); break;
        default:
            for (int i = 0; i < 3; i++) g[i] = NAN;
            for (int i = 0; i < 6; i++) h[i] = NAN;
            return NAN;
        }
    }
}
