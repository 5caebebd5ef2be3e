"""The file formats below the post layer (the model: trimesh's ``exchange``, one module per
format); the one entry point that picks a program's reader is camsmooth.post.load_program, which
also reaches the G-code readers of camsmooth.post.

- table: the one validated CSV table reader (rows, columns, delimiters, BOM, speed)
- ccpath: CC path CSV (CCPath); clcsv: CL CSV; apt: APT CLDATA / NX CLSF; program: CLProgram,
  Tool, ToolPath, ``detect_format`` (format from the content), a result CSV read as a program
- result_csv: camsmooth's result CSV, its columns and reader (written by
  camsmooth.smoothing.output); atomic: atomic writes
"""
