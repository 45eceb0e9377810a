"""Files in and out: problem files (TOML), the command's output folder, gmsh generators."""
