# dualsplit: build the C demo against the Rust static library and run it.
#
#   make demo                      build everything (release) and run block2d
#   make demo DEMO_ARGS="--method pgs --nx 20 --ny 10"
#   make block2d                   only build target/c_examples/block2d
#   make hyperelastic_host         build and run the nonlinear host example
#                                  (its own Newton loop, ds_solve_iteration)
#                                  (target/ is $CARGO_TARGET_DIR when that is set)
#   make clean-c                   remove the C build outputs (not cargo's)
#
# Requires GNU make, cargo and a C99 compiler.

CC      ?= cc
CFLAGS  ?= -O2
CFLAGS  += -std=c99 -Wall -Wextra
CPPFLAGS += -Iinclude
CARGO   ?= cargo
LDLIBS  = -lm -lpthread -ldl

# Cargo's output folder: CARGO_TARGET_DIR when set, as cargo itself does.
TARGETDIR = $(or $(CARGO_TARGET_DIR),target)
LIBDS   = $(TARGETDIR)/release/libdualsplit.a
OUTDIR  = $(TARGETDIR)/c_examples
BLOCK2D = $(OUTDIR)/block2d
HYPER   = $(OUTDIR)/hyperelastic_host
DEMO_ARGS ?=

.PHONY: all demo block2d hyperelastic_host lib clean-c FORCE

all: block2d

demo: block2d
	$(abspath $(BLOCK2D)) $(DEMO_ARGS)

block2d: $(BLOCK2D)

# cargo decides itself whether anything is out of date, so always ask it:
# a recipe of the library itself, so that make reads its time after cargo
# ran (without one, a program could be linked against the library as it
# was before).
lib: $(LIBDS)

$(LIBDS): FORCE
	$(CARGO) build --release

FORCE:

$(BLOCK2D): c_examples/block2d.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) $(CFLAGS) -o $@ c_examples/block2d.c $(LIBDS) $(LDFLAGS) $(LDLIBS)

hyperelastic_host: $(HYPER)
	$(abspath $(HYPER))

$(HYPER): c_examples/hyperelastic_host.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) -Ic_examples $(CFLAGS) -o $@ c_examples/hyperelastic_host.c $(LIBDS) $(LDFLAGS) $(LDLIBS)

$(OUTDIR):
	mkdir -p $@

clean-c:
	rm -rf $(OUTDIR)

# ---------------------------------------------------------------------------------
# Installing like a C library, and the Fortran and SuiteSparse examples
# ---------------------------------------------------------------------------------
#
#   make install PREFIX=/opt/dualsplit    build (release) and install:
#       $(LIBDIR)/libdualsplit.so.$(VERSION), soname libdualsplit.so.$(SOVERSION),
#       with the links libdualsplit.so.$(SOVERSION) and libdualsplit.so
#       $(LIBDIR)/libdualsplit.a
#       $(INCLUDEDIR)/dualsplit.h and $(INCLUDEDIR)/dualsplit.f90 (Fortran module source)
#       $(PKGCONFIGDIR)/dualsplit.pc   (pkg-config --cflags --libs dualsplit)
#       $(CMAKEDIR)/dualsplitConfig.cmake and dualsplitConfigVersion.cmake
#                                      (find_package(dualsplit): dualsplit::dualsplit)
#   make install DESTDIR=/tmp/stage       staged install (packaging)
#   make uninstall PREFIX=...
#   make fortran-demo [DEMO_ARGS=...]     build and run c_examples/block2d.f90 (gfortran)
#   make fortran-minimal                  build and run c_examples/minimal.f90 (gfortran)
#   make fortran-host-iteration           build and run c_examples/host_iteration.f90
#   make suitesparse-demo [DEMO_ARGS=...] build and run c_examples/suitesparse_block2d.c
#                                         (CHOLMOD + CXSparse: libsuitesparse-dev)
#   make fortran-host                     build and run c_examples/host_solver.f90 (the
#                                         library on a Fortran callback's solves)
#   make cholmod-operator-demo [DEMO_ARGS=...] build and run c_examples/cholmod_operator.c
#                                         (the library on CHOLMOD's solves)
#   make petsc-operator-demo [NP=2] [DEMO_ARGS=...] build and run c_examples/petsc_operator.c
#                                         (K in PETSc over MPI: petsc-dev, openmpi-bin)
#   make mumps-demo [DEMO_ARGS=...]       build and run c_examples/mumps_schur.c: K
#                                         factored by the sequential MUMPS, the library
#                                         on its Schur complement (libmumps-seq-dev)
#   make mumps-mpi-demo [DEMO_ARGS=...] [MPIRUN=...] [NP=2]
#                                         the same over MPI: c_examples/mumps_mpi_schur.c
#                                         (libmumps-dev openmpi-bin libopenmpi-dev)
#
# The shared library gets its soname from one extra linker argument given to the
# final rustc call only (`cargo rustc --lib -- -C link-arg=-Wl,-soname,...`):
# dependencies are not rebuilt (RUSTFLAGS would rebuild all of them, and again at
# every switch between `make demo` and `make install`). ELF platforms (Linux, BSD).
# CARGO_TARGET_DIR is honoured; PROFILE=dev installs a debug build.

PREFIX       ?= /usr/local
LIBDIR       ?= $(PREFIX)/lib
INCLUDEDIR   ?= $(PREFIX)/include
PKGCONFIGDIR ?= $(LIBDIR)/pkgconfig
DESTDIR      ?=
PROFILE      ?= release
INSTALL      ?= install

VERSION   := $(shell sed -n 's/^version *= *"\([^"]*\)".*/\1/p' Cargo.toml | head -n 1)
SOVERSION := $(firstword $(subst ., ,$(VERSION)))
SONAME    := libdualsplit.so.$(SOVERSION)
BUILDDIR   = $(TARGETDIR)/$(if $(filter dev,$(PROFILE)),debug,$(PROFILE))
CMAKEDIR  ?= $(LIBDIR)/cmake/dualsplit

ifeq ($(origin FC),default)
FC = gfortran
endif
FFLAGS   ?= -O2
FOUTDIR   = $(OUTDIR)/fortran
SUITESPARSE_CFLAGS ?= -I/usr/include/suitesparse
SUITESPARSE_LIBS   ?= -lcholmod -lcxsparse -lsuitesparseconfig
# Debian's sequential MUMPS (its fake mpi.h in /usr/include/mumps_seq) and parallel one.
MUMPS_SEQ_CFLAGS   ?= -I/usr/include/mumps_seq
MUMPS_SEQ_LIBS     ?= -ldmumps_seq -lmumps_common_seq -lmpiseq_seq -lpord_seq
MUMPS_MPI_LIBS     ?= -ldmumps -lmumps_common
MPICC              ?= mpicc
# OpenMPI refuses to run as root (CI) unless told; --oversubscribe lets 2 ranks run
# on fewer cores.
MPIRUN             ?= OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun --oversubscribe
NP                 ?= 2

.PHONY: install install-lib uninstall fortran-demo fortran-minimal fortran-host fortran-host-iteration suitesparse-demo cholmod-operator-demo petsc-operator-demo \
        mumps-demo mumps-mpi-demo

# Builds libdualsplit.{so,a,rlib} in one rustc call; the link argument only affects
# the shared library.
install-lib:
	$(CARGO) rustc --lib --profile $(PROFILE) -- -C link-arg=-Wl,-soname,$(SONAME)

install: install-lib
	$(INSTALL) -d $(DESTDIR)$(LIBDIR) $(DESTDIR)$(INCLUDEDIR) $(DESTDIR)$(PKGCONFIGDIR)
	$(INSTALL) -m 755 $(BUILDDIR)/libdualsplit.so $(DESTDIR)$(LIBDIR)/libdualsplit.so.$(VERSION)
	ln -sf libdualsplit.so.$(VERSION) $(DESTDIR)$(LIBDIR)/$(SONAME)
	ln -sf $(SONAME) $(DESTDIR)$(LIBDIR)/libdualsplit.so
	$(INSTALL) -m 644 $(BUILDDIR)/libdualsplit.a $(DESTDIR)$(LIBDIR)/libdualsplit.a
	$(INSTALL) -m 644 include/dualsplit.h include/dualsplit.f90 $(DESTDIR)$(INCLUDEDIR)/
	sed -e 's|@PREFIX@|$(PREFIX)|g' -e 's|@LIBDIR@|$(LIBDIR)|g' \
	    -e 's|@INCLUDEDIR@|$(INCLUDEDIR)|g' -e 's|@VERSION@|$(VERSION)|g' \
	    dualsplit.pc.in > $(DESTDIR)$(PKGCONFIGDIR)/dualsplit.pc
	chmod 644 $(DESTDIR)$(PKGCONFIGDIR)/dualsplit.pc
	$(INSTALL) -d $(DESTDIR)$(CMAKEDIR)
	for f in dualsplitConfig dualsplitConfigVersion; do \
	    sed -e 's|@LIBDIR@|$(LIBDIR)|g' -e 's|@INCLUDEDIR@|$(INCLUDEDIR)|g' \
	        -e 's|@VERSION@|$(VERSION)|g' -e 's|@SOVERSION@|$(SOVERSION)|g' \
	        cmake/$$f.cmake.in > $(DESTDIR)$(CMAKEDIR)/$$f.cmake; \
	    chmod 644 $(DESTDIR)$(CMAKEDIR)/$$f.cmake; \
	done

uninstall:
	rm -f $(DESTDIR)$(LIBDIR)/libdualsplit.so $(DESTDIR)$(LIBDIR)/$(SONAME) \
	      $(DESTDIR)$(LIBDIR)/libdualsplit.so.$(VERSION) $(DESTDIR)$(LIBDIR)/libdualsplit.a \
	      $(DESTDIR)$(INCLUDEDIR)/dualsplit.h $(DESTDIR)$(INCLUDEDIR)/dualsplit.f90 \
	      $(DESTDIR)$(PKGCONFIGDIR)/dualsplit.pc \
	      $(DESTDIR)$(CMAKEDIR)/dualsplitConfig.cmake \
	      $(DESTDIR)$(CMAKEDIR)/dualsplitConfigVersion.cmake
	-rmdir $(DESTDIR)$(CMAKEDIR) 2>/dev/null

# The Fortran module is compiled with the programs (gfortran writes dualsplit.mod
# into -J's folder).
$(FOUTDIR)/dualsplit.o: include/dualsplit.f90 | $(OUTDIR)
	mkdir -p $(FOUTDIR)
	$(FC) $(FFLAGS) -J$(FOUTDIR) -c include/dualsplit.f90 -o $@

$(FOUTDIR)/%_f: c_examples/%.f90 $(FOUTDIR)/dualsplit.o $(LIBDS)
	$(FC) $(FFLAGS) -J$(FOUTDIR) -o $@ $< $(FOUTDIR)/dualsplit.o $(LIBDS) $(LDFLAGS) $(LDLIBS)

fortran-demo: $(FOUTDIR)/block2d_f
	$(abspath $(FOUTDIR)/block2d_f) $(DEMO_ARGS)

fortran-minimal: $(FOUTDIR)/minimal_f
	$(abspath $(FOUTDIR)/minimal_f)

fortran-host: $(FOUTDIR)/host_solver_f
	$(abspath $(FOUTDIR)/host_solver_f)

fortran-host-iteration: $(FOUTDIR)/host_iteration_f
	$(abspath $(FOUTDIR)/host_iteration_f)

$(OUTDIR)/suitesparse_block2d: c_examples/suitesparse_block2d.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) $(SUITESPARSE_CFLAGS) $(CFLAGS) -o $@ c_examples/suitesparse_block2d.c \
	    $(LIBDS) $(SUITESPARSE_LIBS) $(LDFLAGS) $(LDLIBS)

suitesparse-demo: $(OUTDIR)/suitesparse_block2d
	$(abspath $(OUTDIR)/suitesparse_block2d) $(DEMO_ARGS)

$(OUTDIR)/mumps_schur: c_examples/mumps_schur.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) $(MUMPS_SEQ_CFLAGS) $(CFLAGS) -o $@ c_examples/mumps_schur.c \
	    $(LIBDS) $(MUMPS_SEQ_LIBS) $(LDFLAGS) $(LDLIBS)

$(OUTDIR)/cholmod_operator: c_examples/cholmod_operator.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) $(SUITESPARSE_CFLAGS) $(CFLAGS) -o $@ c_examples/cholmod_operator.c \
	    $(LIBDS) $(SUITESPARSE_LIBS) $(LDFLAGS) $(LDLIBS)

cholmod-operator-demo: $(OUTDIR)/cholmod_operator
	$(abspath $(OUTDIR)/cholmod_operator) $(DEMO_ARGS)

PETSC_CFLAGS ?= $(shell pkg-config --cflags PETSc)
PETSC_LIBS   ?= $(shell pkg-config --libs PETSc)

$(OUTDIR)/petsc_operator: c_examples/petsc_operator.c include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(MPICC) $(CPPFLAGS) $(PETSC_CFLAGS) -O2 -std=c99 -o $@ c_examples/petsc_operator.c \
	    $(LIBDS) $(PETSC_LIBS) $(LDFLAGS) $(LDLIBS)

petsc-operator-demo: $(OUTDIR)/petsc_operator
	$(MPIRUN) -np $(NP) $(abspath $(OUTDIR)/petsc_operator) $(DEMO_ARGS)

mumps-demo: $(OUTDIR)/mumps_schur
	$(abspath $(OUTDIR)/mumps_schur) $(DEMO_ARGS)

$(OUTDIR)/mumps_mpi_schur: c_examples/mumps_mpi_schur.c c_examples/mumps_schur.c c_examples/block2d_scene.h include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(MPICC) $(CPPFLAGS) $(CFLAGS) -o $@ c_examples/mumps_mpi_schur.c \
	    $(LIBDS) $(MUMPS_MPI_LIBS) $(LDFLAGS) $(LDLIBS)

mumps-mpi-demo: $(OUTDIR)/mumps_mpi_schur
	$(MPIRUN) -np $(NP) $(abspath $(OUTDIR)/mumps_mpi_schur) $(DEMO_ARGS)
