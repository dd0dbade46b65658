"""The shipped muscle presets: FAM1 and FAM2 of the paper (Tables 1-2 geometry, Table 4 laws).

``load_muscle("FAM1")`` reads ``fam1.json`` from here.
"""
