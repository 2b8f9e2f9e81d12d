# dualsplit: build the C demo against the Rust static library and run it.
#
#   make demo                      build everything (release) and run block2d
#   make demo DEMO_ARGS="--method pgs --nx 20 --ny 10"
#   make block2d                   only build target/c_examples/block2d
#   make clean-c                   remove the C build outputs (not cargo's)
#
# Requires GNU make, cargo and a C99 compiler.

CC      ?= cc
CFLAGS  ?= -O2
CFLAGS  += -std=c99 -Wall -Wextra
CPPFLAGS += -Iinclude
CARGO   ?= cargo
LDLIBS  = -lm -lpthread -ldl

LIBDS   = target/release/libdualsplit.a
OUTDIR  = target/c_examples
BLOCK2D = $(OUTDIR)/block2d
DEMO_ARGS ?=

.PHONY: all demo block2d lib clean-c

all: block2d

demo: block2d
	./$(BLOCK2D) $(DEMO_ARGS)

block2d: $(BLOCK2D)

# cargo decides itself whether anything is out of date, so always ask it.
lib:
	$(CARGO) build --release

$(LIBDS): lib

$(BLOCK2D): c_examples/block2d.c include/dualsplit.h $(LIBDS) | $(OUTDIR)
	$(CC) $(CPPFLAGS) $(CFLAGS) -o $@ c_examples/block2d.c $(LIBDS) $(LDFLAGS) $(LDLIBS)

$(OUTDIR):
	mkdir -p $@

clean-c:
	rm -rf $(OUTDIR)
