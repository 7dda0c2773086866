"""The browser runtime: gait agents run in a web page on onnxruntime-web, without Python.

:func:`~emotive.web.export.export_web` (``emotive export web --out DIR``) writes a static
folder: the page (``static/``: the engine loop of ``docs/runtime.md`` in JavaScript, the
scene and controls of the served app), the vendored onnxruntime-web, the whole agent step
as ``agent.onnx``, its metadata as ``agent.json`` and the skinned mannequin; with a crowd
scene (``--scene``, :mod:`~emotive.web.scene`) also ``scene.json``, which the page walks with
recast-navigation's Detour crowd (vendored). Any static file server serves it.
"""
