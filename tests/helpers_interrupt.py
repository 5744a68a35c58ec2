"""The script body both interrupt tests run after their import hook: ``tlm run`` of a small
reflect frame through :func:`tlm.cli.main`, reporting its exit status, whether the hooked module
was imported whole and whether the run folder was written (tests/test_api_interrupt.py with
SIGINT, tests/test_whole_imports_sigterm.py with SIGTERM)."""

import textwrap

CLI_RUN = textwrap.dedent("""
    from tlm.cli import main
    rc = main(["run", "cornell", "--out", "r", "--no-report", "--set", "mode=reflect", "--set",
               "resolution=[16,16]", "--set", "render.spp=1", "--set", "render.light_samples=1"])
    report.update(rc=rc, target_whole=TARGET in sys.modules, out=os.path.exists("r"))
    print(json.dumps(report))
""")
