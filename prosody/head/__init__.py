"""The 3D head that plays FAP streams: its mesh and MPEG-4 feature points (:mod:`.mesh`), the FAP rig that
moves it (:mod:`.rig`), the CPU renderer (:mod:`.render`) and the animated glTF writer (:mod:`.gltf`).

The geometry, the face units and the influence rules are described in ``docs/head.md``.
"""
