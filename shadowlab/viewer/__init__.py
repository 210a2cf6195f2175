"""The interactive viewer (``shadowlab view SCENE``): fly through a scene in a window and switch
between the lab's pictures of it — a technique's shaded image, the ray-traced truth, the error map
against the truth, the texel footprint and the visibility image — with the truth one key away.

Three modules, windowing kept apart from rendering: :mod:`.state` is the pure view state (camera
fly maths, which configuration and view, the key bindings as data, the clock that decides when the
truth is due), :mod:`.script` reads the ``--script`` files that drive the viewer without a person,
:mod:`.render` drives the lab's own pipeline (:mod:`shadowlab.measurement.pipeline`) for one
camera on the lab's headless EGL context and returns images, :mod:`.scene_file` writes the current
view as a scene file that ``compare`` and ``study`` read, and :mod:`.app` is the window
(moderngl-window on pyglet), its input, the HUD and the loop (docs/your-scenes.md#the-viewer).
"""
