"""The one headless GL context and everything that draws with it, shared by every technique: the
context (:mod:`.gl`), the GLSL loader (:mod:`.glsl`), the program cache and uniforms
(:mod:`.programs`), render targets (:mod:`.targets`), full pass state (:mod:`.glstate`), the
frame — a scene uploaded, its G-buffer and exact surface points (:mod:`.frame`) — the shading pass
(:mod:`.shading`), wall-clock timing (:mod:`.timing`), work counters (:mod:`.work`), GPU memory
accounting (:mod:`.memory`) and the allocator setting that keeps per-pixel arrays cheap
(:mod:`.heap`). The shared GLSL programs (G-buffer, shading, lights, full-screen triangle) sit here,
first on the loader's search path.
"""
