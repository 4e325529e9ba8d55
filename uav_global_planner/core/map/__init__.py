"""The map: the voxel grid and what occupies it (ENU, metres, in the planning frame).

``grid`` (bounds and resolution, eqs. 4-7), ``sparse_grid`` (block-sparse masks),
``obstacles`` and ``terrain`` / ``ground`` / ``dem`` (the shapes), ``spatial_index`` (exact
distance queries); the unsafe-node mask at margin gamma (eqs. 8-10): ``inflation`` (whole-grid
masks), ``sparse_inflation`` (block-sparse masks), ``stamping`` (the compiled kernels),
``point_inflation`` and ``dense_inflation`` (point clouds), ``build_steps`` (checkpoints and
threads); ``unknown_space`` (what the map does not show); the airspace: ``airspace`` (fences and
zones of a frame), ``zones`` (their shapes), ``polygons`` (polygon checks), ``zone_checks``
(starts and goals against them); the map updated at run time: ``live_map`` (the builder),
``point_cells`` (the cloud index), ``tiles`` (what a change reaches) and ``mask_buffers`` (masks
re-inflated tile by tile).
"""
