"""``python -m throwaway.command mcsweep|report|hashes ARGS``: the mcsweep command, the
report command, or the config hashes of the built-in experiments (JSON), each in a process
where the throwaway experiment is registered (run with ``tests/registry`` on sys.path)."""

import json
import sys

from mcsweep.experiments.registry import register

from . import SPEC

register(SPEC)

if __name__ == "__main__":
    what, sys.argv = sys.argv[1], [f"mcsweep-{sys.argv[1]}", *sys.argv[2:]]
    if what == "mcsweep":
        from mcsweep.cli import main

        main()
    elif what == "report":
        from mcsweep.report.cli import main

        sys.exit(main(sys.argv[1:]))
    else:
        from omegaconf import OmegaConf

        from mcsweep.command.provenance import config_hash
        from mcsweep.command.validate import compose_config

        jobs = json.loads(sys.argv[1])
        print(json.dumps({" ".join(j): config_hash(OmegaConf.to_container(compose_config(j), resolve=True))
                          for j in jobs}))
