"""Reading what the planner is given: ``scene`` (scene files), ``mapfiles`` (point clouds,
meshes and OctoMaps; one reader per format in ``map_readers``), ``geofence`` (geofence files:
YAML and QGroundControl plans), ``text_files`` (bounded text reading) and ``geodesy`` (WGS-84
<-> ENU).
"""
