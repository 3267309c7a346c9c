// The bundle's entry: window.CaretakerSpatial.{SpatialView, poseCommand, CONTRACT_VERSION, ContractError}.
export { SpatialView } from './spatial_view.js';
export { poseCommand } from './registration.js';
export { CONTRACT_VERSION, ContractError } from './contract.js';
