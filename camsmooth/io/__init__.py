"""Every file format camsmooth reads or writes (the model: trimesh's ``exchange``, one module per
format behind one entry point).

- table: the one validated CSV table reader (rows, columns, delimiters, BOM, speed)
- ccpath: CC path CSV (CCPath); clcsv: CL CSV; apt: APT CLDATA / NX CLSF; program: CLProgram,
  Tool, ToolPath and ``load_program`` (format detected from the content); G-code in every dialect,
  read and written, is camsmooth.post
- output: result CSV; atomic: atomic writes
"""
