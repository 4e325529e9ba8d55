"""Reading what the planner is given: ``scene`` (scene files), ``mapfiles`` (point clouds,
meshes and OctoMaps), ``text_files`` (bounded text reading) and ``geodesy`` (WGS-84 <-> ENU).
"""
