"""The ``uav-plan`` command-line tool: offline planning, the paper's comparison and plots."""
