"""Applications built on the library: the command line, self-check, benchmark, the paper's
experiments. Nothing in the library imports from here."""
