"""Every file format camsmooth reads or writes (the model: trimesh's ``exchange``, one module per
format behind one entry point).

- table: the one validated CSV table reader (rows, columns, delimiters, BOM, speed)
- ccpath: CC path CSV (CCPath); clcsv: CL CSV; apt: APT CLDATA / NX CLSF; gcode: G-code writer
  (dialects, machine / TCP mode) and reader; program: CLProgram, Tool, ToolPath and
  ``load_program`` (format detected from the content)
- output: result CSV; atomic: atomic writes
"""
