"""Layer 3: OpenCL devices and the Runtime that holds one (programs, memory, chunking); it knows
no operation."""
