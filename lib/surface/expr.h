/*
 * expr.h — internal: the expression language of DESIGN.md section 3, compiled to a
 * compact bytecode and evaluated with exact first and second derivatives by
 * forward-mode automatic differentiation.
 *
 * Syntax: optional parameter definitions `NAME = EXPR ;` (each may use earlier
 * parameters), then one formula in x, y, z. Operators + - * / ^ (right associative,
 * binds tighter than unary minus: -x^2 = -(x^2)), parentheses, numbers (C syntax with
 * exponents), pi, functions sqrt exp log sin cos tan tanh abs min max pow atan2.
 *
 * A compiled expression is immutable: evaluation functions take it const and use only
 * the caller's stack, so one expression may be evaluated from several threads at once.
 */
#ifndef ANISTAR_EXPR_H
#define ANISTAR_EXPR_H

#include "core.h"

typedef struct as_expr as_expr;

/* Compile src. On a syntax error returns ANISTAR_EFORMAT with a message naming the
 * column (1-based) and what was expected, e.g.
 *   "expression, column 7: unknown name 'foo'". */
anistar_status as_expr_compile(anistar_context *ctx, const char *src, as_expr **out);
void as_expr_free(anistar_context *ctx, as_expr *e);

/* Value at p. NaN where the expression is undefined (division by zero, log of a
 * negative number, sqrt of a negative number...). */
double as_expr_value(const as_expr *e, const double p[3]);
/* Value and gradient. */
double as_expr_value_grad(const as_expr *e, const double p[3], double g[3]);
/* Value, gradient and Hessian (h: m11 m12 m13 m22 m23 m33). */
double as_expr_value_grad_hess(const as_expr *e, const double p[3], double g[3], double h[6]);

/* The value of a parameter defined in the expression (e.g. "R" in
 * "R=10; r=1; ..."); returns 0 and sets *v if found, -1 otherwise. */
int as_expr_param(const as_expr *e, const char *name, double *v);

#endif /* ANISTAR_EXPR_H */
