import os

from hypothesis import HealthCheck, settings

# CI runs thousands of examples per property (the protocol issue asks for it); a developer's
# run stays quick. FIELDBOX_HYPOTHESIS=ci forces the long profile locally.
settings.register_profile("dev", max_examples=300, deadline=None)
settings.register_profile("ci", max_examples=3000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("FIELDBOX_HYPOTHESIS") or ("ci" if os.environ.get("CI") else "dev"))
