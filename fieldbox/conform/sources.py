"""Where each case's rule is written: the names every case table cites.

Each names a section of ``docs/protocol.md`` (in the repository, so a reader of a report can
look it up), which restates the rule with its origin: a table of one of the seed documents
(the community's reverse-engineered protocol pages), fieldbox's protocol notes (what real
peers do where the seeds are silent or wrong) or the capture of a real NI DS and roboRIO
(2021). The words a case quotes after a name are those of that origin; the section says the
same in its own words.
"""

NOTES = "docs/protocol.md"
ROBOT_SIDE = f"{NOTES}#rio-behaviour"
DS_DETAILS = f"{NOTES}#ds-to-rio-details"
DS_FMS = f"{NOTES}#ds-to-fms"
FIELD = f"{NOTES}#fms-behaviour"
CORRECTIONS = f"{NOTES}#corrections"
TRAPS = f"{NOTES}#traps"
SEED_D2R = f"{NOTES}#ds-to-rio (seed ds_to_rio.rst)"
SEED_R2D = f"{NOTES}#rio-to-ds (seed rio_to_ds.rst)"
SEED_F2D = f"{NOTES}#fms-to-ds (seed fms_to_ds.rst)"
CAPTURE = f"capture ni-ds-roborio-2021.pcapng ({NOTES}#sources)"
