/*
 * expr.h — internal: the expression language of DESIGN.md section 3, compiled to a
 * compact bytecode and evaluated with exact first and second derivatives by
 * forward-mode automatic differentiation.
 *
 * Syntax (whitespace anywhere between tokens; names are case-sensitive):
 *   program := { NAME '=' expr ';' } expr [';']
 *   expr    := term { ('+'|'-') term }        term   := signed { ('*'|'/') signed }
 *   signed  := { '+'|'-' } power              power  := primary [ '^' signed ]
 *   primary := NUMBER | x | y | z | pi | PARAM | FUNC '(' expr {',' expr} ')' | '(' expr ')'
 *   NUMBER  := ( D+ ['.' D*] | '.' D+ ) [ ('e'|'E') ['+'|'-'] D+ ]     NAME := [A-Za-z_][A-Za-z0-9_]*
 * so ^ is right associative and binds tighter than unary minus (-x^2 = -(x^2),
 * 2^3^2 = 512, x^-2 = 1/x^2). Functions: sqrt exp log sin cos tan tanh abs (1 argument),
 * pow atan2 (2), min max (2 or more). Parameters are constants evaluated once, at
 * compile time: they may use numbers, pi, functions and earlier parameters, never
 * x, y, z; they cannot be redefined nor take a reserved name (x y z pi, function names);
 * their values must be finite. A trailing ';' after the formula is allowed.
 *
 * Semantics: IEEE double arithmetic in the order written (the compiler's rewritings are
 * exact, so values are bitwise those of the formula evaluated as written), except:
 * division by exactly zero and zero to a negative power give NaN (not +-inf); integer
 * constant exponents use repeated squaring (x^3 == x*(x*x), exact signs for negative
 * bases); other exponents use pow (NaN for a negative base); x^0 == 1. log of a
 * negative number and sqrt of a negative number are NaN, log(0) = -inf. Evaluation never
 * traps. At kinks the derivative of one branch is taken: abs(u) at u == 0 that of +u,
 * min / max at a tie that of the first argument.
 *
 * A compiled expression is immutable: evaluation functions take it const and use only
 * the caller's stack, so one expression may be evaluated from several threads at once.
 */
#ifndef ANISTAR_EXPR_H
#define ANISTAR_EXPR_H

#include "core.h"

typedef struct as_expr as_expr;

/* The evaluation stack has this many slots (on the caller's stack: 80 bytes each for
 * value_grad_hess, about 10 KiB); as_expr_compile rejects expressions that would need
 * more (only deeply nested pow / atan2 / min / max calls can: + - * / are reordered so
 * that any nesting of them needs few slots). */
#define AS_EXPR_MAX_STACK 128

/* Compile src. On a syntax error returns ANISTAR_EFORMAT with a message naming the
 * column (1-based) and what was expected, e.g.
 *   "expression, column 7: unknown name 'foo' (the variables are x, y, z)".
 * ANISTAR_ENOMEM when the context allocator fails; ANISTAR_EINVAL for NULL arguments.
 * *out is NULL on failure. The parser uses no recursion: nesting depth is limited only
 * by memory (and AS_EXPR_MAX_STACK, see above). */
anistar_status as_expr_compile(anistar_context *ctx, const char *src, as_expr **out);
/* Free e (NULL is ok); ctx must be the context it was compiled with. */
void as_expr_free(anistar_context *ctx, as_expr *e);

/* Value at p (e non-NULL). NaN where the expression is undefined (division by zero, log
 * of a negative number, sqrt of a negative number...). */
double as_expr_value(const as_expr *e, const double p[3]);
/* Value and gradient. The value is bitwise that of as_expr_value. */
double as_expr_value_grad(const as_expr *e, const double p[3], double g[3]);
/* Value, gradient and Hessian (h: m11 m12 m13 m22 m23 m33). Value and gradient are
 * bitwise those of as_expr_value_grad. */
double as_expr_value_grad_hess(const as_expr *e, const double p[3], double g[3], double h[6]);

/* The value of a parameter defined in the expression (e.g. "R" in
 * "R=10; r=1; ..."); returns 0 and sets *v if found, -1 otherwise. */
int as_expr_param(const as_expr *e, const char *name, double *v);

/* The number of parameters, and the i-th one (in definition order): *name is owned by e.
 * as_expr_param_at returns 0, or -1 when i is out of range. */
size_t as_expr_param_count(const as_expr *e);
int as_expr_param_at(const as_expr *e, size_t i, const char **name, double *v);

/* Which variables the compiled formula refers to: bit 0 x, bit 1 y, bit 2 z (0 for a
 * constant formula). A variable multiplied by 0 still counts. */
int as_expr_uses_xyz(const as_expr *e);
/* 1 iff the compiled code applies abs, min or max (to something that depends on x, y or
 * z: constant subexpressions are folded at compile time): the function may have kinks,
 * its derivatives jump there. */
int as_expr_has_kinks(const as_expr *e);

/* The number of evaluation stack slots the bytecode needs (1..AS_EXPR_MAX_STACK) and
 * its length in instructions (for tests and benchmarks). */
int as_expr_stack_depth(const as_expr *e);
size_t as_expr_code_size(const as_expr *e);

#endif /* ANISTAR_EXPR_H */
