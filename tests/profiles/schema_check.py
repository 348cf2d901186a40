#!/usr/bin/env python3
# Validates profile files against profiles/schema/profile.schema.json with python3-jsonschema, a validator
# nobody here wrote. Usage: schema_check.py SCHEMA FILE...; exit 1 when any file breaks the schema.
import json, sys, jsonschema
schema = json.load(open(sys.argv[1]))
jsonschema.Draft202012Validator.check_schema(schema)
v = jsonschema.Draft202012Validator(schema)
bad = 0
for f in sys.argv[2:]:
    d = json.load(open(f))
    if d.get("format") != "mbscope-profile/1": continue  # shared map files, not profiles
    errs = list(v.iter_errors(d))
    for e in errs[:5]: print(f, "/".join(map(str, e.absolute_path)), e.message[:200])
    bad += len(errs)
print("errors", bad)
sys.exit(1 if bad else 0)
