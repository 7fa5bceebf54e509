"""Rendering the reconstructed scene (paper §5): evidence views, stereo, lighting, export, video.

:mod:`.views` and :mod:`.lighting` turn the project's named views and lighting presets into
cameras and lights (pure numpy); :mod:`.scene` gathers the model's mesh and its extracted textures;
:mod:`.renderer` draws them with moderngl, off-screen or into a window; :mod:`.export` writes glTF
and OBJ; :mod:`.video` renders a walk-through to MP4. Nothing here imports GL until a renderer is
made.
"""
