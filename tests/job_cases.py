# SPDX-License-Identifier: GPL-2.0-or-later
"""Bad combinations of a job's options, shared by the front ends' tests: each the
same job given on the command line, as a recipe and through qgis_process, and the
one message every front end must give (tests/cli/test_job_rules.py,
tests/qgis/test_qgis_process.py).

EX and SK stand for an exemplar DEM and a sketch.  The QGIS form is None where
QGIS's own form refuses the value before the job is built (a number below the
parameter's minimum, no exemplar layer): QGIS says that in its words."""

# (command, CLI arguments after it, the recipe's job element, QGIS parameters, message)
CASES = [
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--alpha-r", "1"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='alpha_r'>1</Param></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "ALPHA_R": 1},
     "alpha_r applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--layout", "0.5"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='layout'>0.5</Param></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "LAYOUT": 0.5},
     "layout applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--mode", "valleys"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/>"
     "<Param name='mode'>valleys</Param></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "MODE": 1},
     "mode applies to a sketch: give sketch"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--alpha-h", "2"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Heights alpha='2'/></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "ALPHA_H": 2},
     "alpha_h weighs heights: give heights"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--water", "EX"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Water>EX</Water></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "WATER_MASK": "EX"},
     "water and water_level go together"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--regions", "EX"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Regions>EX</Regions></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "REGIONS": "EX"},
     "regions and region_exemplar go together"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--regions", "EX", "--region-exemplar",
               "1=EX", "--region-exemplar", "1=EX"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100'/><Regions>EX</Regions>"
     "<RegionExemplar id='1'>EX</RegionExemplar><RegionExemplar id='1'>EX</RegionExemplar>"
     "</Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "REGIONS": "EX",
      "REGION_EXEMPLARS": "1=EX;1=EX"},
     "region_exemplar: region 1 is given twice"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--crs", "EPSG:32616"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='100' height='100' crs='EPSG:32616'/></Synth>",
     {"EXEMPLARS": "EX", "WIDTH": 100, "HEIGHT": 100, "CRS": "EPSG:32616"},
     "a CRS needs an origin and a resolution"),
    ("synth", ["--exemplar", "EX", "--sketch", "SK", "--size", "100x100"],
     "<Synth><Exemplar>EX</Exemplar><Sketch>SK</Sketch><Grid width='100' height='100'/></Synth>",
     {"EXEMPLARS": "EX", "SKETCH": "SK", "WIDTH": 100, "HEIGHT": 100},
     "a sketch sets the output grid: give no size"),
    ("synth", ["--exemplar", "EX", "--like", "EX", "--resolution", "30"],
     "<Synth><Exemplar>EX</Exemplar><Grid like='EX' resolution='30'/></Synth>",
     {"EXEMPLARS": "EX", "LIKE": "EX", "RESOLUTION": 30},
     "like sets the output grid: give no resolution"),
    ("synth", ["--exemplar", "EX"],
     "<Synth><Exemplar>EX</Exemplar></Synth>",
     {"EXEMPLARS": "EX"},
     "give the target grid: a sketch, like or size"),
    ("synth", ["--size", "100x100"],
     "<Synth><Grid width='100' height='100'/></Synth>",
     None,
     "needs at least one exemplar"),
    ("synth", ["--exemplar", "EX", "--size", "100x100", "--seed", "-1"],
     "<Synth seed='-1'><Exemplar>EX</Exemplar><Grid width='100' height='100'/></Synth>",
     None,
     "seed must be a whole number in 0..18446744073709551615, not '-1'"),
    ("synth", ["--exemplar", "EX", "--size", "0x100"],
     "<Synth><Exemplar>EX</Exemplar><Grid width='0' height='100'/></Synth>",
     None,
     "size takes WxH in cells (1..65536), not '0x100'"),
    ("ppa", ["EX", "--threshold", "5", "--threshold-fraction", "0.01"],
     "<PPA><Input>EX</Input><Param name='threshold'>5</Param>"
     "<Param name='threshold_fraction'>0.01</Param></PPA>",
     {"INPUT": "EX", "THRESHOLD": 5, "THRESHOLD_FRACTION": 0.01},
     "give threshold or threshold_fraction, not both"),
    ("ppa", ["EX", "--band", "0"],
     "<PPA><Input band='0'>EX</Input></PPA>",
     None,
     "band must be a whole number in 1..65535, not '0'"),
]
