"""The map: the voxel grid and what occupies it (ENU, metres, in the planning frame).

``grid`` (bounds and resolution, eqs. 4-7), ``sparse_grid`` (block-sparse masks),
``obstacles`` and ``terrain`` / ``ground`` / ``dem`` (the shapes), ``spatial_index`` (exact
distance queries), ``inflation`` and ``dense_inflation`` (the unsafe-node mask at margin gamma,
eqs. 8-10), ``unknown_space`` (what the map does not show), ``airspace`` (fences and zones) and
``live_map`` (the map updated at run time).
"""
