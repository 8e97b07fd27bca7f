"""Where each case's rule is written: the names every case table cites.

The seed documents (``shared/seeds/``), fieldbox's PROTOCOL-NOTES (what real peers do where
the seeds are silent or wrong) and the capture of a real NI DS and roboRIO (2021).
"""

NOTES = "PROTOCOL-NOTES"
ROBOT_SIDE = f'{NOTES} "How a real roboRIO (and WPILib\'s simulator) behaves"'
DS_DETAILS = f'{NOTES} "Driver Station -> roboRIO details"'
DS_FMS = f'{NOTES} "Driver Station -> FMS (no seed document)"'
FIELD = f'{NOTES} "How a real FMS behaves (field side)"'
CORRECTIONS = f'{NOTES} "Corrections from real captures and peers"'
TRAPS = f'{NOTES} "Known traps in other implementations"'
SEED_D2R = "seed ds_to_rio.rst"
SEED_R2D = "seed rio_to_ds.rst"
SEED_F2D = "seed fms_to_ds.rst"
CAPTURE = "capture ni-ds-roborio-2021.pcapng"
