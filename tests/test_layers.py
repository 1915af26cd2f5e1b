"""The house: imports point down the layers of docs/architecture.md (the import-linter contract in pyproject.toml),
no module imports another package's private module or name, and the library never imports demos or
benchmarks (the command line finds them by name at run time, from a clone)."""

from pathlib import Path

import pytest

from benchmarks.structure import analyse

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def report():
    return analyse(ROOT, run_contract=True)


def test_the_import_contract_is_kept(report):
    contract = report["import_contract"]
    assert contract is not None, report["import_contract_reason"]
    assert contract["exit_code"] == 0 and contract["broken"] == 0 and contract["violations"] == 0, contract
    assert contract["kept"] >= 1


def test_no_module_imports_another_packages_private_module(report):
    private = report["private_imports"]
    assert private["count"] == 0, "\n".join(private["list"])
    assert not private["unresolved"], private["unresolved"]


def test_the_library_never_imports_demos_or_benchmarks(report):
    reached = report["cross_layer"]
    assert reached["count"] == 0 and reached["dynamic"]["count"] == 0, reached["list"] + reached["dynamic"]["list"]
    # the command line names them (strings it imports by at run time), and nothing else in the library does
    assert {item["file"] for item in reached["module_name_strings"]["items"]} <= {"mcl/tools/cli.py"}


def test_the_widest_parameter_list_outside_the_kernels_is_about_a_dozen(report):
    # (the fused step's 59 parameters are ten groups now; a few model kernels still take up to about twenty)
    widest = report["widest_parameters"]
    assert widest["outside_kernels"]["widest"]["parameters"] <= 14, widest["outside_kernels"]["top"]
    assert widest["kernels"]["widest"]["parameters"] <= 22, widest["kernels"]["top"]
