// node validate.js FILE.glb -> prints the validator's JSON report (issues.numErrors etc.)
const fs = require("fs");
const validator = require("gltf-validator");
const data = new Uint8Array(fs.readFileSync(process.argv[2]));
validator.validateBytes(data, { maxIssues: 100 })
  .then((report) => console.log(JSON.stringify(report)))
  .catch((err) => { console.error(String(err)); process.exit(1); });
