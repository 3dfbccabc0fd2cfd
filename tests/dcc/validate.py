"""Validate DCC files against PTB's DCC 3.2.0 schema (with D-SI 2.1.0), offline.

usage: python3 validate.py SCHEMA_DIR FILE...

SCHEMA_DIR holds dcc_3_2_0.xsd and SI_Format_2_1_0.xsd (../shared/data/dcc);
the W3C XML-Signature schema the DCC imports is the one xmlschema ships.
Prints one line per file ("FILE: N errors" and the first errors); exits 1
when any file is invalid.
"""
import os
import sys

import xmlschema

here = sys.argv[1]
dsig = os.path.join(os.path.dirname(xmlschema.__file__), "schemas/DSIG/xmldsig-core-schema.xsd")
schema = xmlschema.XMLSchema(
    os.path.join(here, "dcc_3_2_0.xsd"),
    locations=[
        ("https://ptb.de/si", os.path.join(here, "SI_Format_2_1_0.xsd")),
        ("http://www.w3.org/2000/09/xmldsig#", dsig),
    ],
)
invalid = 0
for path in sys.argv[2:]:
    errors = list(schema.iter_errors(path))
    print(f"{path}: {len(errors)} errors")
    for e in errors[:5]:
        print(f"  {e.path}: {e.reason}")
    invalid += bool(errors)
sys.exit(1 if invalid else 0)
