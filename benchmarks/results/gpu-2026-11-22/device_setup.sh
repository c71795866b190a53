# sourced at the start of every device command
python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .devcarry/whl/*.whl || exit 1
export PYTHONPATH=$PWD/src:/tmp/site:$PWD/.devcarry/site THERMOCAL_DATA=$PWD/.devcarry/data PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1
