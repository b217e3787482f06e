/* granflow's Abaqus UMAT (docs/umat.md): the frictional-only and the phase-transition models
 * behind the standard UMAT entry point, for Abaqus/Standard and codes that accept UMATs.
 * Fortran calling convention: every argument by reference, CMNAME's length as a hidden last
 * argument (gfortran and Intel Fortran on Linux: size_t). Arrays are Fortran (column-major). */
#ifndef GRANFLOW_UMAT_H
#define GRANFLOW_UMAT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* PROPS(1): which model. */
#define GRANFLOW_UMAT_FRICTIONAL 1
#define GRANFLOW_UMAT_PHASE_TRANSITION 2
/* NPROPS of each model and the least NSTATV (layout in docs/umat.md). */
#define GRANFLOW_UMAT_NPROPS_FRICTIONAL 14
#define GRANFLOW_UMAT_NPROPS_PHASE_TRANSITION 21
#define GRANFLOW_UMAT_NSTATV 13

void umat_(double* stress, double* statev, double* ddsdde, double* sse, double* spd, double* scd, double* rpl,
           double* ddsddt, double* drplde, double* drpldt, const double* stran, const double* dstran,
           const double* time, const double* dtime, const double* temp, const double* dtemp,
           const double* predef, const double* dpred, const char* cmname, const int* ndi, const int* nshr,
           const int* ntens, const int* nstatv, const double* props, const int* nprops, const double* coords,
           const double* drot, double* pnewdt, const double* celent, const double* dfgrd0,
           const double* dfgrd1, const int* noel, const int* npt, const int* layer, const int* kspt,
           const int* jstep, const int* kinc, size_t cmname_len);

/* The message of this thread's last rejected call, "material M, element E, point P: ..." ("" after
 * an accepted one). The first time a message occurs it is also written to stderr. */
const char* granflow_umat_last_error(void);

#ifdef __cplusplus
}
#endif

#endif
