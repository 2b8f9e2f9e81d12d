/*
 * mumps_mpi_schur.c -- mumps_schur.c over MPI with the parallel MUMPS: K
 * distributed over the ranks (ICNTL(18) = 3, each rank passes the entries of its
 * own elements), the Schur complement onto the contact DOFs and the right-hand
 * side centralised on the host (ICNTL(19) = 1), dualsplit called on rank 0 only,
 * the multipliers broadcast, the expansion of u run by all ranks and broadcast.
 * The workflow and the checks are mumps_schur.c's (see there).
 *
 * Build and run (Debian: apt-get install libmumps-dev openmpi-bin; see the
 * Makefile):
 *   make mumps-mpi-demo [MPIRUN_FLAGS=...] [DEMO_ARGS=...]
 *   mpicc -O2 -Iinclude c_examples/mumps_mpi_schur.c target/release/libdualsplit.a \
 *         -ldmumps -lmumps_common -lm -lpthread -ldl -o mumps_mpi_schur
 *   mpirun -np 2 ./mumps_mpi_schur
 */
#define MUMPS_SCHUR_MPI 1
#include "mumps_schur.c"
